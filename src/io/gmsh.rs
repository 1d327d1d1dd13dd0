//! gmsh MSH 4.1 files: reading (ASCII and binary) and writing (ASCII).
//!
//! Reading keeps what curving needs — node coordinates and element blocks with
//! their entity tags — and skips every other section ($Entities,
//! $PhysicalNames, $Periodic, ...). Malformed input gives [`Error::Io`] with a
//! message naming the line (ASCII) or byte offset (binary) and the section; the
//! reader never panics on bad input.
//!
//! ```
//! use hocurve::io::gmsh::{parse_msh, to_linear_mesh};
//! let msh = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n\
//!     $Nodes\n1 3 1 3\n2 1 0 3\n1\n2\n3\n0 0 0\n1 0 0\n0 1 0\n$EndNodes\n\
//!     $Elements\n1 1 1 1\n2 1 2 1\n1 1 2 3\n$EndElements\n";
//! let mesh = to_linear_mesh(&parse_msh(msh).unwrap()).unwrap();
//! assert_eq!((mesh.dim, mesh.cells.clone()), (2, vec![0, 1, 2]));
//! ```

use super::{io_err, push_f64, push_usize, write_atomically, write_f64, write_formatted, CellMeshView};
use crate::error::{Error, Result};
use crate::mesh::LinearMesh;
use crate::reference::ordering::{gmsh_element_shape, gmsh_element_type, gmsh_multi_indices, gmsh_type_info};
use crate::reference::Simplex;
use std::collections::HashMap;
use std::io::Write;
use std::path::Path;

/// The nodes and elements of an MSH file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MshContent {
    /// Node coordinates, in file order.
    pub nodes: Vec<[f64; 3]>,
    /// Element blocks, in file order.
    pub blocks: Vec<ElementBlock>,
}

/// One block of elements of a single type on one geometric entity.
#[derive(Debug, Clone, PartialEq)]
pub struct ElementBlock {
    /// Dimension of the geometric entity (0..=3).
    pub entity_dim: usize,
    /// Tag of the geometric entity (point, curve, surface or volume).
    pub entity_tag: i32,
    /// gmsh element type (2 = 3-node triangle, 4 = 4-node tet, 1 = line, ...).
    pub element_type: i32,
    /// Nodes per element of `element_type`.
    pub nodes_per_element: usize,
    /// Element nodes, 0-based into [`MshContent::nodes`], gmsh's local order.
    pub connectivity: Vec<usize>,
}

impl ElementBlock {
    /// Number of elements in the block.
    pub fn n_elements(&self) -> usize {
        self.connectivity.len().checked_div(self.nodes_per_element).unwrap_or(0)
    }
}

/// Parses an MSH 4.1 file held in a string (ASCII format).
pub fn parse_msh(text: &str) -> Result<MshContent> {
    parse_msh_bytes(text.as_bytes())
}

/// Parses an MSH 4.1 file, ASCII or binary.
pub fn parse_msh_bytes(data: &[u8]) -> Result<MshContent> {
    Parser::new(data).parse()
}

/// Reads an MSH 4.1 file (ASCII or binary).
pub fn read_msh(path: &Path) -> Result<MshContent> {
    let data = std::fs::read(path).map_err(|e| Error::Io(format!("{}: {e}", path.display())))?;
    parse_msh_bytes(&data).map_err(|e| match e {
        Error::Io(m) => Error::Io(format!("{}: {m}", path.display())),
        e => e,
    })
}

/// The linear mesh to curve.
///
/// Its dimension is the highest one having 3-node triangles (type 2) or 4-node
/// tetrahedra (type 4); its cells are all elements of that dimension, which
/// must all be of that type. Facets are the elements of dimension `dim − 1`
/// (2-node lines in 2D, 3-node triangles in 3D), tagged with their entity tag;
/// in 3D, feature edges are the 2-node lines, tagged with their curve tag.
/// Vertices are the nodes used by cells, renumbered in file order; a facet or
/// edge using any other node is an error. In 2D the z coordinate is dropped.
pub fn to_linear_mesh(msh: &MshContent) -> Result<LinearMesh> {
    let dim = if msh.blocks.iter().any(|b| b.element_type == 4) {
        3
    } else if msh.blocks.iter().any(|b| b.element_type == 2) {
        2
    } else {
        let found = match msh.blocks.iter().max_by_key(|b| b.entity_dim) {
            Some(b) if b.entity_dim >= 2 => format!(
                " (found element type {} on entity {}: the mesh to curve must be linear simplices only)",
                b.element_type, b.entity_tag
            ),
            _ => String::new(),
        };
        return Err(Error::Io(format!("no linear triangles (type 2) or tetrahedra (type 4) in the mesh{found}")));
    };
    let (cell_type, facet_type) = if dim == 3 { (4, 2) } else { (2, 1) };
    let mut cells = Vec::new();
    let mut facets = Vec::new();
    let mut facet_tags = Vec::new();
    let mut feature_edges = Vec::new();
    let mut feature_edge_tags = Vec::new();
    for b in &msh.blocks {
        let wrong = |what: &str| {
            Err(Error::Io(format!(
                "element type {} on {what} entity {} (dim {}): the mesh to curve must be \
                 linear simplices only",
                b.element_type, b.entity_tag, b.entity_dim
            )))
        };
        if b.entity_dim == dim {
            if b.element_type != cell_type {
                return wrong("cell");
            }
            cells.extend_from_slice(&b.connectivity);
        } else if b.entity_dim + 1 == dim {
            if b.element_type != facet_type {
                return wrong("facet");
            }
            facets.extend_from_slice(&b.connectivity);
            facet_tags.extend(std::iter::repeat_n(b.entity_tag, b.n_elements()));
        } else if dim == 3 && b.entity_dim == 1 {
            if b.element_type != 1 {
                return wrong("edge");
            }
            feature_edges.extend_from_slice(&b.connectivity);
            feature_edge_tags.extend(std::iter::repeat_n(b.entity_tag, b.n_elements()));
        }
    }
    let (coords, new_index) = compact(msh, &cells, dim)?;
    let renumber = |list: &mut Vec<usize>, what: &str| -> Result<()> {
        for v in list.iter_mut() {
            *v = new_index
                .get(*v)
                .copied()
                .flatten()
                .ok_or_else(|| Error::Io(format!("a {what} uses node {} which is in no cell", *v + 1)))?;
        }
        Ok(())
    };
    renumber(&mut cells, "cell")?;
    renumber(&mut facets, "facet")?;
    renumber(&mut feature_edges, "feature edge")?;
    Ok(LinearMesh { dim, coords, cells, facets, facet_tags, feature_edges, feature_edge_tags })
}

/// The high-order cells of the highest dimension having complete Lagrange
/// triangles or tetrahedra: `(simplex, order, coords, cells)` with `coords`
/// interleaved with `simplex.dim()` components (the nodes used by the cells,
/// renumbered in file order) and `cells` in gmsh's local node order
/// ([`gmsh_multi_indices`]). All cells must have the same type.
pub fn high_order_cells(msh: &MshContent) -> Result<(Simplex, usize, Vec<f64>, Vec<usize>)> {
    let dim = msh
        .blocks
        .iter()
        .filter_map(|b| gmsh_type_info(b.element_type))
        .map(|(s, _)| s.dim())
        .max()
        .ok_or_else(|| Error::Io("no Lagrange triangles or tetrahedra in the mesh".into()))?;
    let mut kind: Option<(i32, Simplex, usize)> = None;
    let mut cells = Vec::new();
    for b in msh.blocks.iter().filter(|b| b.entity_dim == dim) {
        match (kind, gmsh_type_info(b.element_type)) {
            (None, Some((s, p))) if s.dim() == dim => kind = Some((b.element_type, s, p)),
            (Some((t, _, _)), _) if t == b.element_type => {}
            _ => {
                return Err(Error::Io(format!(
                    "element type {} on entity {} (dim {dim}): cells of mixed or \
                     non-simplex types",
                    b.element_type, b.entity_tag
                )))
            }
        }
        cells.extend_from_slice(&b.connectivity);
    }
    let Some((_, simplex, order)) = kind else {
        return Err(Error::Io(format!("no cells of dimension {dim}")));
    };
    let (coords, new_index) = compact(msh, &cells, dim)?;
    for v in cells.iter_mut() {
        // Every cell node is in `new_index` by construction.
        *v = new_index.get(*v).copied().flatten().unwrap_or(usize::MAX);
    }
    Ok((simplex, order, coords, cells))
}

/// Coordinates (`dim` components) of the nodes used by `cells`, in file order,
/// and the new index of every old node (`None` if unused).
fn compact(msh: &MshContent, cells: &[usize], dim: usize) -> Result<(Vec<f64>, Vec<Option<usize>>)> {
    let mut used = vec![false; msh.nodes.len()];
    for &v in cells {
        *used
            .get_mut(v)
            .ok_or_else(|| Error::Io(format!("cell node index {v} out of range ({} nodes)", msh.nodes.len())))? = true;
    }
    let mut new_index = vec![None; msh.nodes.len()];
    let mut coords = Vec::new();
    let mut n = 0;
    for (i, x) in msh.nodes.iter().enumerate() {
        if used[i] {
            new_index[i] = Some(n);
            n += 1;
            coords.extend_from_slice(&x[..dim]);
        }
    }
    Ok((coords, new_index))
}

/// Writes an order-p simplex mesh as MSH 4.1 ASCII (atomically, see [`crate::io`]).
pub fn write_msh(path: &Path, mesh: &CellMeshView) -> Result<()> {
    write_atomically(path, |w| write_msh_to(w, mesh))
}

/// Writes an order-p simplex mesh as MSH 4.1 ASCII: one entity of dimension
/// `dim` with tag 1 holding every node and cell, cells converted from
/// `mesh.cell_multi`'s order to gmsh's.
pub fn write_msh_to<W: Write>(w: W, mesh: &CellMeshView) -> Result<()> {
    write_msh_parts_to(w, mesh, None)
}

/// Writes a mesh split into parts in gmsh's partitioned MSH 4.1 format
/// (atomically, see [`crate::io`]); see [`write_msh_parts_to`].
pub fn write_msh_partitioned(path: &Path, mesh: &CellMeshView, part: &[usize], parts: usize) -> Result<()> {
    write_atomically(path, |w| write_msh_parts_to(w, mesh, Some((part, parts))))
}

/// [`write_msh_to`], or with `partition` = (the part of each cell, the
/// number of parts) gmsh's partitioned format: the model entity, and under
/// `$PartitionedEntities` one entity per part (tag part + 2, its parent the
/// model entity) holding the part's cells and the nodes it owns (those
/// whose lowest part among their cells' is it). Node and cell tags are the
/// same either way: index + 1.
pub fn write_msh_parts_to<W: Write>(mut w: W, mesh: &CellMeshView, partition: Option<(&[usize], usize)>) -> Result<()> {
    let perm = mesh.checked_permutation(&gmsh_multi_indices(mesh.simplex, mesh.order))?;
    let ty = gmsh_element_type(mesh.simplex, mesh.order)
        .ok_or_else(|| Error::InvalidInput(format!("no gmsh type for order {}", mesh.order)))?;
    let dim = mesh.simplex.dim();
    let (n, ne, npc) = (mesh.n_nodes(), mesh.n_cells(), mesh.nodes_per_cell());
    // Per cell and node, the part (0 without a partition).
    let (part_of_cell, parts): (Vec<usize>, usize) = match partition {
        None => (vec![0; ne], 1),
        Some((part, parts)) => {
            if part.len() != ne || part.iter().any(|&p| p >= parts) {
                return Err(Error::InvalidInput(format!("a partition into {parts} parts of {} cells", part.len())));
            }
            (part.to_vec(), parts)
        }
    };
    let mut part_of_node = vec![usize::MAX; n];
    for (cell, &p) in mesh.cells.chunks_exact(npc).zip(&part_of_cell) {
        for &k in cell {
            part_of_node[k] = part_of_node[k].min(p);
        }
    }
    let nodes_of: Vec<Vec<usize>> = (0..parts).map(|p| (0..n).filter(|&i| part_of_node[i] == p).collect()).collect();
    let cells_of: Vec<Vec<usize>> = (0..parts).map(|p| (0..ne).filter(|&c| part_of_cell[c] == p).collect()).collect();
    let tag = |p: usize| if partition.is_some() { p + 2 } else { 1 };
    let w = &mut w;
    (|| -> std::io::Result<()> {
        writeln!(w, "$MeshFormat\n4.1 0 8\n$EndMeshFormat")?;
        writeln!(w, "$Entities")?;
        writeln!(w, "0 0 {} {}", usize::from(dim == 2), usize::from(dim == 3))?;
        write!(w, "1")?;
        write_bounding_box(w, mesh, 0..n)?;
        writeln!(w, " 0 0\n$EndEntities")?;
        if partition.is_some() {
            writeln!(w, "$PartitionedEntities\n{parts}\n0")?;
            writeln!(w, "0 0 {} {}", if dim == 2 { parts } else { 0 }, if dim == 3 { parts } else { 0 })?;
            for p in 0..parts {
                write!(w, "{} {dim} 1 1 {}", tag(p), p + 1)?;
                let nodes = cells_of[p].iter().flat_map(|&c| mesh.cells[c * npc..(c + 1) * npc].iter().copied());
                write_bounding_box(w, mesh, nodes)?;
                writeln!(w, " 0 0")?;
            }
            writeln!(w, "$EndPartitionedEntities")?;
        }
        let blocks = (0..parts).filter(|&p| !nodes_of[p].is_empty()).count();
        writeln!(w, "$Nodes\n{blocks} {n} 1 {n}")?;
        for (p, nodes) in nodes_of.iter().enumerate().filter(|(_, v)| !v.is_empty()) {
            writeln!(w, "{dim} {} 0 {}", tag(p), nodes.len())?;
            write_node_block(w, mesh, nodes)?;
        }
        writeln!(w, "$EndNodes")?;
        let blocks = (0..parts).filter(|&p| !cells_of[p].is_empty()).count();
        writeln!(w, "$Elements\n{blocks} {ne} 1 {ne}")?;
        for (p, cells) in cells_of.iter().enumerate().filter(|(_, v)| !v.is_empty()) {
            writeln!(w, "{dim} {} {ty} {}", tag(p), cells.len())?;
            write_cell_block(w, mesh, cells, &perm)?;
        }
        writeln!(w, "$EndElements")?;
        w.flush()
    })()
    .map_err(io_err)
}

/// The lines of a `$Nodes` block after its header: the tags of `nodes`
/// (index + 1), then their coordinates.
fn write_node_block<W: Write>(w: &mut W, mesh: &CellMeshView, nodes: &[usize]) -> std::io::Result<()> {
    write_formatted(w, nodes.len(), |k, buf| {
        push_usize(buf, nodes[k] + 1);
        buf.push(b'\n');
    })?;
    write_formatted(w, nodes.len(), |k, buf| {
        for (c, &x) in mesh.node(nodes[k]).iter().enumerate() {
            if c > 0 {
                buf.push(b' ');
            }
            push_f64(buf, x);
        }
        buf.push(b'\n');
    })
}

/// The lines of an `$Elements` block after its header: each of `cells`'
/// tag (index + 1), then its nodes' tags in gmsh's order (`perm`).
fn write_cell_block<W: Write>(w: &mut W, mesh: &CellMeshView, cells: &[usize], perm: &[usize]) -> std::io::Result<()> {
    let npc = mesh.nodes_per_cell();
    write_formatted(w, cells.len(), |c, buf| {
        let e = cells[c];
        push_usize(buf, e + 1);
        for &k in perm {
            buf.push(b' ');
            push_usize(buf, mesh.cells[e * npc + k] + 1);
        }
        buf.push(b'\n');
    })
}

/// The smallest and largest coordinates of `nodes` of `mesh`, each written
/// after a space.
fn write_bounding_box<W: Write>(
    w: &mut W,
    mesh: &CellMeshView,
    nodes: impl Iterator<Item = usize>,
) -> std::io::Result<()> {
    let (mut lo, mut hi) = ([0.0f64; 3], [0.0f64; 3]);
    for (k, i) in nodes.enumerate() {
        let x = mesh.node(i);
        for c in 0..3 {
            if k == 0 || x[c] < lo[c] {
                lo[c] = x[c];
            }
            if k == 0 || x[c] > hi[c] {
                hi[c] = x[c];
            }
        }
    }
    for x in lo.iter().chain(&hi) {
        write!(w, " ")?;
        write_f64(w, *x)?;
    }
    Ok(())
}

/// A cursor over an MSH file: whitespace-separated tokens for ASCII parts,
/// fixed-size values for binary parts.
struct Parser<'a> {
    data: &'a [u8],
    pos: usize,
    line: usize,
    section: &'static str,
    binary: Option<Binary>,
}

/// Layout of binary data: `size_t` width and byte order.
#[derive(Clone, Copy)]
struct Binary {
    size_t: usize,
    little: bool,
}

impl<'a> Parser<'a> {
    fn new(data: &'a [u8]) -> Self {
        Parser { data, pos: 0, line: 1, section: "header", binary: None }
    }

    fn err(&self, msg: impl std::fmt::Display) -> Error {
        let at = match self.binary {
            Some(_) if self.section != "$MeshFormat" => format!("byte {}", self.pos),
            _ => format!("line {}", self.line),
        };
        Error::Io(format!("msh {at} (in {}): {msg}", self.section))
    }

    fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    /// A capacity for `n` items of at least `bytes` bytes each that the rest
    /// of the file can actually hold (headers are untrusted).
    fn cap(&self, n: usize, bytes: usize) -> usize {
        n.min(self.remaining() / bytes.max(1))
    }

    /// Next whitespace-separated token, `None` at end of input.
    fn token(&mut self) -> Result<Option<&'a str>> {
        while let Some(&c) = self.data.get(self.pos) {
            if !c.is_ascii_whitespace() {
                break;
            }
            if c == b'\n' {
                self.line += 1;
            }
            self.pos += 1;
        }
        let start = self.pos;
        while let Some(&c) = self.data.get(self.pos) {
            if c.is_ascii_whitespace() {
                break;
            }
            self.pos += 1;
        }
        if start == self.pos {
            return Ok(None);
        }
        let bytes = self.data.get(start..self.pos).unwrap_or_default();
        std::str::from_utf8(bytes).map(Some).map_err(|_| self.err("invalid UTF-8 in text"))
    }

    fn expect(&mut self, what: &str) -> Result<&'a str> {
        self.token()?.ok_or_else(|| self.err(format!("unexpected end of file, expected {what}")))
    }

    fn expect_exact(&mut self, want: &str) -> Result<()> {
        let t = self.expect(want)?;
        if t == want {
            Ok(())
        } else {
            Err(self.err(format!("expected {want}, found '{t}' (wrong counts?)")))
        }
    }

    fn usize(&mut self, what: &str) -> Result<usize> {
        if let Some(b) = self.binary {
            return self.bin_size_t(b, what);
        }
        let t = self.expect(what)?;
        t.parse().map_err(|_| self.err(format!("expected {what} (an unsigned integer), found '{t}'{}", early_end(t))))
    }

    fn i32(&mut self, what: &str) -> Result<i32> {
        if let Some(b) = self.binary {
            let bytes = self.bin_bytes::<4>(what)?;
            return Ok(if b.little { i32::from_le_bytes(bytes) } else { i32::from_be_bytes(bytes) });
        }
        let t = self.expect(what)?;
        t.parse().map_err(|_| self.err(format!("expected {what} (an integer), found '{t}'{}", early_end(t))))
    }

    fn f64(&mut self, what: &str) -> Result<f64> {
        let x = if let Some(b) = self.binary {
            let bytes = self.bin_bytes::<8>(what)?;
            if b.little {
                f64::from_le_bytes(bytes)
            } else {
                f64::from_be_bytes(bytes)
            }
        } else {
            let t = self.expect(what)?;
            t.parse().map_err(|_| self.err(format!("expected {what} (a number), found '{t}'{}", early_end(t))))?
        };
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.err(format!("non-finite {what} {x}")))
        }
    }

    fn bin_bytes<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        let bytes = self
            .data
            .get(self.pos..self.pos.saturating_add(N))
            .and_then(|s| <[u8; N]>::try_from(s).ok())
            .ok_or_else(|| self.err(format!("unexpected end of file, expected {what}")))?;
        self.pos += N;
        Ok(bytes)
    }

    fn bin_size_t(&mut self, b: Binary, what: &str) -> Result<usize> {
        let v = if b.size_t == 4 {
            let x = self.bin_bytes::<4>(what)?;
            u64::from(if b.little { u32::from_le_bytes(x) } else { u32::from_be_bytes(x) })
        } else {
            let x = self.bin_bytes::<8>(what)?;
            if b.little {
                u64::from_le_bytes(x)
            } else {
                u64::from_be_bytes(x)
            }
        };
        usize::try_from(v).map_err(|_| self.err(format!("{what} {v} too large")))
    }

    /// After a section name in a binary file: the single newline before the data.
    fn binary_data_start(&mut self) -> Result<()> {
        if self.data.get(self.pos) == Some(&b'\r') {
            self.pos += 1;
        }
        if self.data.get(self.pos) != Some(&b'\n') {
            return Err(self.err("expected a newline before binary data"));
        }
        self.pos += 1;
        self.line += 1;
        Ok(())
    }

    fn parse(mut self) -> Result<MshContent> {
        self.expect_exact("$MeshFormat").map_err(|_| self.err("not an MSH file: it must start with $MeshFormat"))?;
        self.section = "$MeshFormat";
        self.mesh_format()?;
        let mut msh = MshContent::default();
        let mut tags: Vec<usize> = Vec::new();
        let (mut have_nodes, mut have_elements) = (false, false);
        loop {
            self.section = "file body";
            let Some(name) = self.token()? else { break };
            if !name.starts_with('$') || name.starts_with("$End") {
                return Err(self.err(format!("expected a section name, found '{name}'")));
            }
            match name {
                "$Nodes" => {
                    self.section = "$Nodes";
                    self.nodes(&mut msh.nodes, &mut tags)?;
                    have_nodes = true;
                }
                "$Elements" => {
                    self.section = "$Elements";
                    self.elements(&mut msh.blocks)?;
                    have_elements = true;
                }
                _ => self.skip_section(name)?,
            }
        }
        if !have_nodes {
            return Err(Error::Io("msh: missing $Nodes section".into()));
        }
        if !have_elements {
            return Err(Error::Io("msh: missing $Elements section".into()));
        }
        resolve_tags(&mut msh, &tags)?;
        Ok(msh)
    }

    fn mesh_format(&mut self) -> Result<()> {
        let version = self.expect("the format version")?;
        if version != "4.1" {
            return Err(self.err(format!(
                "MSH version {version} is not supported: save as 4.1 \
                 (gmsh option Mesh.MshFileVersion = 4.1)"
            )));
        }
        let file_type = self.usize("the file type")?;
        let size_t = self.usize("the data size")?;
        match (file_type, size_t) {
            (0, _) => {}
            (1, 4 | 8) => {
                self.binary_data_start()?;
                let one = self.bin_bytes::<4>("the binary endianness check")?;
                let little = if i32::from_le_bytes(one) == 1 {
                    true
                } else if i32::from_be_bytes(one) == 1 {
                    false
                } else {
                    return Err(self.err("bad binary endianness check (expected the integer 1)"));
                };
                self.binary = Some(Binary { size_t, little });
            }
            _ => return Err(self.err(format!("unsupported file type {file_type} / data size {size_t}"))),
        }
        self.expect_exact("$EndMeshFormat")
    }

    /// Skips a section this reader does not need, up to its `$End...` line.
    fn skip_section(&mut self, name: &str) -> Result<()> {
        let section = name.strip_prefix('$').unwrap_or(name);
        let end = format!("$End{section}");
        if self.binary.is_some() {
            // Binary payloads are not tokens: look for the end marker line.
            let pat = format!("\n{end}");
            let rest = self.data.get(self.pos..).unwrap_or_default();
            let at = rest
                .windows(pat.len())
                .position(|w| w == pat.as_bytes())
                .ok_or_else(|| self.err(format!("missing {end}")))?;
            self.pos += at + pat.len();
            return Ok(());
        }
        while let Some(t) = self.token()? {
            if t == end {
                return Ok(());
            }
        }
        Err(self.err(format!("unexpected end of file, missing {end}")))
    }

    /// The header of the `$Nodes` or `$Elements` section (`what`: "node" or
    /// "element"): the numbers of blocks and of items; the tag range is skipped.
    fn section_header(&mut self, what: &str) -> Result<(usize, usize)> {
        if self.binary.is_some() {
            self.binary_data_start()?;
        }
        let n_blocks = self.usize(&format!("the number of {what} blocks"))?;
        let n_items = self.usize(&format!("the number of {what}s"))?;
        self.usize(&format!("the minimum {what} tag"))?;
        self.usize(&format!("the maximum {what} tag"))?;
        Ok((n_blocks, n_items))
    }

    fn nodes(&mut self, nodes: &mut Vec<[f64; 3]>, tags: &mut Vec<usize>) -> Result<()> {
        let (n_blocks, n_nodes) = self.section_header("node")?;
        let first = nodes.len();
        nodes.reserve(self.cap(n_nodes, 8));
        tags.reserve(self.cap(n_nodes, 8));
        for _ in 0..n_blocks {
            let entity_dim = self.i32("the entity dimension")?;
            self.i32("the entity tag")?;
            let parametric = self.i32("the parametric flag")?;
            let n = self.usize("the number of nodes in the block")?;
            let extra = match (parametric, entity_dim) {
                (0, 0..=3) => 0,
                (1, d @ 0..=3) => d as usize,
                _ => {
                    return Err(
                        self.err(format!("bad node block header (entity dim {entity_dim}, parametric {parametric})"))
                    )
                }
            };
            for _ in 0..n {
                let tag = self.usize("a node tag")?;
                if tag == 0 {
                    return Err(self
                        .err("node tag 0: tags start at 1 (or the block header announces more nodes than it holds)"));
                }
                tags.push(tag);
            }
            for _ in 0..n {
                let x = [self.f64("an x coordinate")?, self.f64("a y coordinate")?, self.f64("a z coordinate")?];
                for _ in 0..extra {
                    self.f64("a parametric coordinate")?;
                }
                nodes.push(x);
            }
        }
        if nodes.len() - first != n_nodes {
            return Err(
                self.err(format!("the header announces {n_nodes} nodes, the blocks hold {}", nodes.len() - first))
            );
        }
        self.expect_exact("$EndNodes")
    }

    fn elements(&mut self, blocks: &mut Vec<ElementBlock>) -> Result<()> {
        let (n_blocks, n_elements) = self.section_header("element")?;
        let mut total = 0usize;
        for _ in 0..n_blocks {
            let entity_dim = self.i32("the entity dimension")?;
            let entity_tag = self.i32("the entity tag")?;
            let element_type = self.i32("the element type")?;
            let n = self.usize("the number of elements in the block")?;
            let (dim, npe) = gmsh_element_shape(element_type)
                .ok_or_else(|| self.err(format!("unsupported element type {element_type}")))?;
            if usize::try_from(entity_dim).ok() != Some(dim) {
                return Err(
                    self.err(format!("element type {element_type} (dim {dim}) on an entity of dim {entity_dim}"))
                );
            }
            let mut connectivity = Vec::with_capacity(self.cap(n.saturating_mul(npe), 2));
            for _ in 0..n {
                self.usize("an element tag")?;
                for _ in 0..npe {
                    connectivity.push(self.usize("an element node tag")?);
                }
            }
            total = total.saturating_add(n);
            blocks.push(ElementBlock {
                entity_dim: dim,
                entity_tag,
                element_type,
                nodes_per_element: npe,
                connectivity,
            });
        }
        if total != n_elements {
            return Err(self.err(format!("the header announces {n_elements} elements, the blocks hold {total}")));
        }
        self.expect_exact("$EndElements")
    }
}

/// A hint for a number that is a section marker: the section ended before
/// its counts said it would.
fn early_end(token: &str) -> &'static str {
    if token.starts_with('$') {
        " (the section ends early: wrong counts?)"
    } else {
        ""
    }
}

/// Replaces node tags by 0-based node indices in every block.
fn resolve_tags(msh: &mut MshContent, tags: &[usize]) -> Result<()> {
    let max = tags.iter().copied().max().unwrap_or(0);
    let dense = max <= 2 * tags.len() + 1024;
    let mut dense_map = Vec::new();
    let mut sparse_map = HashMap::new();
    let duplicate = |t: usize| Err(Error::Io(format!("msh $Nodes: node tag {t} appears twice")));
    if dense {
        dense_map = vec![usize::MAX; max + 1];
        for (i, &t) in tags.iter().enumerate() {
            if std::mem::replace(&mut dense_map[t], i) != usize::MAX {
                return duplicate(t);
            }
        }
    } else {
        sparse_map.reserve(tags.len());
        for (i, &t) in tags.iter().enumerate() {
            if sparse_map.insert(t, i).is_some() {
                return duplicate(t);
            }
        }
    }
    for b in &mut msh.blocks {
        for v in b.connectivity.iter_mut() {
            let i = if dense {
                dense_map.get(*v).copied().filter(|&i| i != usize::MAX)
            } else {
                sparse_map.get(v).copied()
            };
            *v = i.ok_or_else(|| {
                Error::Io(format!(
                    "msh $Elements: element block of type {} on entity {} uses unknown node tag {}",
                    b.element_type, b.entity_tag, *v
                ))
            })?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::ordering::vtk_multi_indices;

    /// A unit square [0,2]×[0,1] in two triangles with tagged boundary curves;
    /// nodes in two entity blocks with non-contiguous tags.
    const SQUARE: &str = "$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
1
2 1 \"my domain\"
$EndPhysicalNames
$Entities
0 2 1 0
1 0 0 0 2 0 0 0 0
2 0 0 0 2 1 0 1 7 0
1 0 0 0 2 1 0 1 1 2 1 2
$EndEntities
$Nodes
2 5 10 50
1 1 0 3
10
30
20
0 0 0
2 0 0
2 1 0
2 1 0 2
50
40
0 1 0
1 0.5 0
$EndNodes
$Elements
3 4 1 4
1 1 1 1
1 10 30
1 2 1 1
2 20 50
2 1 2 2
3 10 30 40
4 20 50 40
$EndElements
";

    #[test]
    fn parses_square_into_linear_mesh() {
        let msh = parse_msh(SQUARE).unwrap();
        assert_eq!(msh.nodes.len(), 5);
        assert_eq!(msh.blocks.len(), 3);
        let mesh = to_linear_mesh(&msh).unwrap();
        assert_eq!(mesh.dim, 2);
        // Nodes in file order: tags 10, 30, 20, 50, 40.
        assert_eq!(mesh.coords, vec![0., 0., 2., 0., 2., 1., 0., 1., 1., 0.5]);
        assert_eq!(mesh.cells, vec![0, 1, 4, 2, 3, 4]);
        assert_eq!(mesh.facets, vec![0, 1, 2, 3]);
        assert_eq!(mesh.facet_tags, vec![1, 2]);
        assert!(mesh.feature_edges.is_empty());
    }

    const TET: &str = "$MeshFormat
4.1 0 8
$EndMeshFormat
$Nodes
1 5 1 5
3 1 0 5
1
2
3
4
5
0 0 0
1 0 0
0 1 0
0 0 1
9 9 9
$EndNodes
$Elements
4 4 1 4
3 1 4 1
1 1 2 3 4
2 5 2 1
2 1 3 2
1 8 1 1
3 1 2
0 3 15 1
4 4
$EndElements
";

    #[test]
    fn parses_tet_with_facets_and_feature_edges() {
        let mesh = to_linear_mesh(&parse_msh(TET).unwrap()).unwrap();
        assert_eq!(mesh.dim, 3);
        assert_eq!(mesh.n_vertices(), 4); // node 5 is in no cell
        assert_eq!(mesh.cells, vec![0, 1, 2, 3]);
        assert_eq!((mesh.facets.clone(), mesh.facet_tags.clone()), (vec![0, 2, 1], vec![5]));
        assert_eq!(mesh.feature_edges, vec![0, 1]);
        assert_eq!(mesh.feature_edge_tags, vec![8]);
    }

    #[test]
    fn facet_on_node_outside_cells_is_an_error() {
        let bad = TET.replace("2 1 3 2\n", "2 1 3 5\n");
        assert!(matches!(to_linear_mesh(&parse_msh(&bad).unwrap()), Err(Error::Io(_))));
    }

    #[test]
    fn high_order_cells_are_rejected_by_to_linear_mesh() {
        let bad = SQUARE
            .replace("3 4 1 4", "3 3 1 4")
            .replace("2 1 2 2\n3 10 30 40\n4 20 50 40", "2 1 9 1\n3 10 30 40 20 50 40");
        let msh = parse_msh(&bad).unwrap();
        assert!(matches!(to_linear_mesh(&msh), Err(Error::Io(_))));
        let (s, p, coords, cells) = high_order_cells(&msh).unwrap();
        assert_eq!((s, p, coords.len(), cells.len()), (Simplex::Tri, 2, 10, 6));
    }

    fn assert_io_err(text: &str, needle: &str) {
        match parse_msh(text) {
            Err(Error::Io(m)) => assert!(m.contains(needle), "{m:?} lacks {needle:?}"),
            other => panic!("expected an Io error containing {needle:?}, got {other:?}"),
        }
    }

    #[test]
    fn malformed_files_are_io_errors() {
        assert_io_err("", "$MeshFormat");
        assert_io_err("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n", "version 2.2");
        assert_io_err("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n", "missing $Nodes");
        let no_elements = TET.split("$Elements").next().unwrap().to_string();
        assert_io_err(&no_elements, "missing $Elements");
        assert_io_err(&TET.replace("1 5 1 5", "1 6 1 5"), "announces 6 nodes");
        assert_io_err(&TET.replace("3 1 0 5", "3 1 0 6"), "$Nodes");
        assert_io_err(&TET.replace("4 4 1 4", "4 5 1 4"), "announces 5 elements");
        assert_io_err(&TET.replace("1 1 2 3 4", "1 1 2 3 44"), "unknown node tag 44");
        assert_io_err(&TET.replace("9 9 9", "9 nan 9"), "non-finite");
        assert_io_err(&TET.replace("9 9 9", "9 9 x"), "line 16");
        assert_io_err(&TET.replace("3\n4\n5\n", "3\n3\n5\n"), "appears twice");
        assert_io_err(&TET.replace("3 1 4 1", "3 1 999 1"), "unsupported element type 999");
        assert_io_err(&TET.replace("3 1 4 1", "2 1 4 1"), "on an entity of dim 2");
        assert_io_err(&TET.replace("$EndElements\n", ""), "$EndElements");
        assert_io_err(&TET.replace("$EndNodes", "$EndNode"), "expected $EndNodes");
        assert_io_err(&SQUARE.replace("$EndPhysicalNames", ""), "missing $EndPhysicalNames");
        // Every truncation of a valid file is an error, never a panic.
        for cut in 0..TET.len() - 1 {
            if TET.is_char_boundary(cut) {
                assert!(parse_msh(&TET[..cut]).is_err(), "cut at {cut}");
            }
        }
    }

    #[test]
    fn huge_announced_counts_do_not_allocate() {
        let text = TET.replace("1 5 1 5\n3 1 0 5", "1 5 1 5\n3 1 0 999999999999999999");
        assert!(parse_msh(&text).is_err());
        let text = TET.replace("4 4 1 4", "4 4 1 18446744073709551615");
        assert!(parse_msh(&text).is_ok()); // max tag is informational
    }

    #[test]
    fn mutated_files_never_panic() {
        // Deterministic byte mutations of valid ASCII and binary files: the
        // reader and the conversions must return, whatever the bytes.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut rand = move |n: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % n as u64) as usize
        };
        let alphabet = b"0123456789 -.\n$eE\xff\x00";
        for base in [TET.as_bytes().to_vec(), SQUARE.as_bytes().to_vec(), tet_binary()] {
            for _ in 0..3000 {
                let mut data = base.clone();
                for _ in 0..1 + rand(3) {
                    let i = rand(data.len());
                    data[i] = alphabet[rand(alphabet.len())];
                }
                if let Ok(msh) = parse_msh_bytes(&data) {
                    let _ = to_linear_mesh(&msh);
                    let _ = high_order_cells(&msh);
                }
            }
        }
    }

    fn grid_nodes(simplex: Simplex, p: usize, multi: &[[usize; 4]], cells: usize) -> Vec<f64> {
        // Cell c is the reference simplex shifted by 2c along x; nodes not shared.
        let d = simplex.dim();
        let mut coords = Vec::new();
        for c in 0..cells {
            for a in multi {
                coords.push(2.0 * c as f64 + a[1] as f64 / p as f64);
                for &ai in &a[2..=d] {
                    coords.push(ai as f64 / p as f64 + 0.1 * c as f64);
                }
            }
        }
        coords
    }

    fn round_trip(simplex: Simplex, p: usize) {
        // The caller's local order: VTK's, so the writer must permute.
        let multi = vtk_multi_indices(simplex, p);
        let npc = multi.len();
        let coords = grid_nodes(simplex, p, &multi, 2);
        let cells: Vec<usize> = (0..2 * npc).rev().collect();
        let view = CellMeshView { simplex, order: p, coords: &coords, cells: &cells, cell_multi: &multi };
        let mut buf = Vec::new();
        write_msh_to(&mut buf, &view).unwrap();
        let msh = parse_msh(std::str::from_utf8(&buf).unwrap()).unwrap();
        let (s, order, c2, cells2) = high_order_cells(&msh).unwrap();
        assert_eq!((s, order), (simplex, p));
        // Permute back from gmsh's order to the caller's.
        let back = crate::reference::ordering::permutation(&gmsh_multi_indices(simplex, p), &multi).unwrap();
        let d = simplex.dim();
        for (cell, cell2) in cells.chunks(npc).zip(cells2.chunks(npc)) {
            for k in 0..npc {
                let (i, j) = (cell[k], cell2[back[k]]);
                assert_eq!(coords[i * d..(i + 1) * d], c2[j * d..(j + 1) * d]);
            }
        }
    }

    #[test]
    fn write_then_parse_recovers_order_3_tets() {
        round_trip(Simplex::Tet, 3);
    }

    #[test]
    fn write_then_parse_recovers_order_4_triangles() {
        round_trip(Simplex::Tri, 4);
    }

    /// The partitioned format: one entity per part, the nodes each in the
    /// block of the lowest part holding them; read back (the reader skips
    /// $PartitionedEntities), the same cells on the same node positions.
    #[test]
    fn a_partitioned_mesh_reads_back_as_the_same_cells() {
        let (simplex, p) = (Simplex::Tet, 2);
        let multi = gmsh_multi_indices(simplex, p);
        let npc = multi.len();
        let coords = grid_nodes(simplex, p, &multi, 2);
        let cells: Vec<usize> = (0..2 * npc).collect();
        let view = CellMeshView { simplex, order: p, coords: &coords, cells: &cells, cell_multi: &multi };
        let mut buf = Vec::new();
        write_msh_parts_to(&mut buf, &view, Some((&[1, 0], 2))).unwrap();
        let text = std::str::from_utf8(&buf).unwrap();
        assert!(text.contains("$PartitionedEntities\n2\n0\n0 0 0 2\n2 3 1 1 1 "), "{text}");
        assert!(text.contains("$Elements\n2 2 1 2\n3 2 11 1\n2 "), "part 0 (entity 2) holds cell 2: {text}");
        let msh = parse_msh(text).unwrap();
        let (_, _, c2, cells2) = high_order_cells(&msh).unwrap();
        let d = simplex.dim();
        let positions = |c: &[f64], cell: &[usize]| -> Vec<Vec<u64>> {
            cell.iter().map(|&i| c[i * d..(i + 1) * d].iter().map(|x| x.to_bits()).collect()).collect()
        };
        let mut written: Vec<_> = cells.chunks(npc).map(|c| positions(&coords, c)).collect();
        let mut read: Vec<_> = cells2.chunks(npc).map(|c| positions(&c2, c)).collect();
        written.sort();
        read.sort();
        assert_eq!(written, read);
        let bad = write_msh_parts_to(Vec::new(), &view, Some((&[0, 2], 2)));
        assert!(matches!(bad, Err(Error::InvalidInput(_))), "{bad:?}");
    }

    #[test]
    fn write_rejects_a_bad_view() {
        let multi = gmsh_multi_indices(Simplex::Tri, 2);
        let coords = [0.0; 12];
        let cells = [0, 1, 2, 3, 4, 6];
        let view = CellMeshView { simplex: Simplex::Tri, order: 2, coords: &coords, cells: &cells, cell_multi: &multi };
        assert!(matches!(write_msh_to(Vec::new(), &view), Err(Error::InvalidInput(_))));
        let view = CellMeshView { cells: &cells[..5], ..view };
        assert!(write_msh_to(Vec::new(), &view).is_err());
        let view = CellMeshView { cells: &[0, 1, 2, 3, 4, 5], cell_multi: &multi[..5], ..view };
        assert!(write_msh_to(Vec::new(), &view).is_err());
    }

    /// The binary encoding of `TET` (little-endian, 8-byte size_t), built by hand.
    fn tet_binary() -> Vec<u8> {
        let mut b = b"$MeshFormat\n4.1 1 8\n".to_vec();
        b.extend(1i32.to_le_bytes());
        b.extend(b"\n$EndMeshFormat\n$Entities\n");
        b.extend([0u8; 32]);
        b.extend(b"\n$EndEntities\n$Nodes\n");
        let st = |b: &mut Vec<u8>, v: u64| b.extend(v.to_le_bytes());
        let int = |b: &mut Vec<u8>, v: i32| b.extend(v.to_le_bytes());
        for v in [1, 4, 1, 4] {
            st(&mut b, v);
        }
        for v in [3, 1, 1] {
            int(&mut b, v); // dim 3, tag 1, parametric (u v w follow)
        }
        st(&mut b, 4);
        for v in 1..=4 {
            st(&mut b, v);
        }
        for x in [[0f64, 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]] {
            for c in x.iter().chain(&[0.5, 0.5, 0.5]) {
                b.extend(c.to_le_bytes());
            }
        }
        b.extend(b"\n$EndNodes\n$Elements\n");
        for v in [2, 2, 1, 2] {
            st(&mut b, v);
        }
        for v in [3, 1, 4] {
            int(&mut b, v);
        }
        st(&mut b, 1);
        for v in [1, 1, 2, 3, 4] {
            st(&mut b, v);
        }
        for v in [2, 5, 2] {
            int(&mut b, v);
        }
        st(&mut b, 1);
        for v in [2, 1, 3, 2] {
            st(&mut b, v);
        }
        b.extend(b"\n$EndElements\n");
        b
    }

    #[test]
    fn parses_binary_msh() {
        let data = tet_binary();
        let mesh = to_linear_mesh(&parse_msh_bytes(&data).unwrap()).unwrap();
        assert_eq!(mesh.dim, 3);
        assert_eq!(mesh.coords[3..6], [1., 0., 0.]);
        assert_eq!(mesh.cells, vec![0, 1, 2, 3]);
        assert_eq!((mesh.facets, mesh.facet_tags), (vec![0, 2, 1], vec![5]));
        for cut in 0..data.len() - 1 {
            assert!(parse_msh_bytes(&data[..cut]).is_err(), "cut at {cut}");
        }
    }

    /// Files written by gmsh itself (scripts/gen_gmsh_samples.py) and the
    /// counts gmsh's API reported for them.
    fn gmsh_sample(name: &str) -> (MshContent, [usize; 6]) {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
        let expected = std::fs::read_to_string(dir.join("gmsh_samples_expected.txt")).unwrap();
        let row = expected.lines().find(|l| l.split_whitespace().next() == Some(name)).unwrap();
        let v: Vec<usize> = row.split_whitespace().skip(1).map(|t| t.parse().unwrap()).collect();
        let msh = read_msh(&dir.join(name)).unwrap();
        (msh, [v[0], v[1], v[2], v[3], v[4], v[5]])
    }

    fn signed_measure(mesh: &LinearMesh, cell: &[usize]) -> f64 {
        let x: Vec<[f64; 3]> = cell.iter().map(|&v| mesh.vertex(v)).collect();
        let e = |i: usize, c: usize| x[i][c] - x[0][c];
        if mesh.dim == 2 {
            e(1, 0) * e(2, 1) - e(1, 1) * e(2, 0)
        } else {
            e(1, 0) * (e(2, 1) * e(3, 2) - e(2, 2) * e(3, 1)) - e(1, 1) * (e(2, 0) * e(3, 2) - e(2, 2) * e(3, 0))
                + e(1, 2) * (e(2, 0) * e(3, 1) - e(2, 1) * e(3, 0))
        }
    }

    #[test]
    fn reads_linear_meshes_written_by_gmsh() {
        for name in ["plate_hole_2d.msh", "plate_hole_2d_bin.msh", "box_3d.msh"] {
            let (msh, [dim, nv, nc, nf, ne, _]) = gmsh_sample(name);
            let mesh = to_linear_mesh(&msh).unwrap();
            assert_eq!((mesh.dim, mesh.n_vertices(), mesh.n_cells(), mesh.n_facets()), (dim, nv, nc, nf), "{name}");
            assert_eq!(mesh.feature_edges.len() / 2, ne, "{name}");
            assert_eq!(mesh.feature_edge_tags.len(), ne, "{name}");
            assert!(mesh.facet_tags.iter().all(|&t| t > 0));
            for cell in mesh.cells.chunks(dim + 1) {
                assert!(signed_measure(&mesh, cell) > 0.0, "{name}: inverted cell");
            }
        }
        let ascii = to_linear_mesh(&gmsh_sample("plate_hole_2d.msh").0).unwrap();
        let binary = to_linear_mesh(&gmsh_sample("plate_hole_2d_bin.msh").0).unwrap();
        // gmsh's ASCII keeps 16 significant digits, its binary all 17.
        assert_eq!((&ascii.cells, &ascii.facets), (&binary.cells, &binary.facets));
        assert_eq!(ascii.facet_tags, binary.facet_tags);
        let gap = ascii.coords.iter().zip(&binary.coords).map(|(a, b)| (a - b).abs());
        assert!(gap.fold(0.0, f64::max) < 1e-14);
    }

    #[test]
    fn reads_quadratic_tets_written_by_gmsh_in_gmsh_order() {
        let (msh, [_, nv, nc, _, _, order]) = gmsh_sample("box_3d_p2.msh");
        assert!(matches!(to_linear_mesh(&msh), Err(Error::Io(_))));
        let (simplex, p, coords, cells) = high_order_cells(&msh).unwrap();
        assert_eq!((simplex, p, coords.len() / 3, cells.len() / 10), (Simplex::Tet, order, nv, nc));
        // The box is straight-sided: every node sits at its multi-index's
        // barycentric combination of the cell's vertices.
        let multi = gmsh_multi_indices(Simplex::Tet, 2);
        let x = |v: usize| [coords[3 * v], coords[3 * v + 1], coords[3 * v + 2]];
        for cell in cells.chunks(10) {
            for (k, a) in multi.iter().enumerate() {
                for c in 0..3 {
                    let want: f64 = (0..4).map(|i| a[i] as f64 / 2.0 * x(cell[i])[c]).sum();
                    assert!((x(cell[k])[c] - want).abs() < 1e-12);
                }
            }
        }
    }
}
