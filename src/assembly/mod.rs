//! Element kernels (local) and the sparse scatter (global).
//!
//! The sparsity pattern of the reduced system K_ff (free degrees of freedom
//! only, lower triangle) is built once per mesh in [`DofMap::pattern`] and
//! reused by every assembly. Dirichlet conditions are applied by elimination:
//! the coupling K_fd u_d goes to the right-hand side as the elements are
//! visited, so K_fd is never stored.
//!
//! Assembly is parallel (rayon), lock-free and deterministic: cells are
//! coloured so that no two cells of one colour share a vertex (hence no
//! node); colours are processed one after the other and the cells of a colour
//! in parallel, so every global entry receives its contributions in the same
//! order whatever the number of threads: results are bitwise reproducible.

mod condense;
mod hyperelastic;
mod kernel;
mod lines;
mod matrix_free;
pub mod transfer;

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

pub use condense::{condense_element, CondenseWorkspace, InteriorRecovery, LocalSplit};
pub use hyperelastic::{MaterialKernel, TangentMode};
pub use kernel::LinearElasticKernel;
pub use lines::cell_lines;
pub use transfer::multigrid_levels;

use crate::mesh::{HighOrderMesh, NodeConstraint};
use crate::sparse::SymmetricCsc;
use crate::{Error, Result};

/// Numbering of the degrees of freedom: dof = node · dim + component. The
/// free dofs are numbered node by node in [`locality_order`], a node's
/// components together; with static condensation
/// ([`DofMap::condensed`]) the cell-interior ones come after all others, and
/// the global system holds only the first `n_system`.
#[derive(Debug, Clone)]
pub struct DofMap {
    pub dim: usize,
    /// `free[dof]` = index among the free dofs, or `usize::MAX` if prescribed
    /// (read through [`DofMap::role`]).
    free: Vec<usize>,
    pub n_free: usize,
    /// Unknowns of the assembled system: the free dofs below `n_system`
    /// (`n_free` without condensation).
    pub n_system: usize,
    /// The cells' interior and boundary local dofs, with condensation.
    split: Option<LocalSplit>,
}

/// What one degree of freedom is in the assembled system ([`DofMap::role`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DofRole {
    /// Its value is given: a boundary node's.
    Prescribed,
    /// An unknown of the assembled system, at this row (index among the free dofs).
    System(usize),
    /// A cell-interior unknown condensed out of the system and recovered
    /// after each solve, at this index among the free dofs (`n_system` or more).
    Interior(usize),
}

impl DofMap {
    /// Every boundary node (fixed or on an entity) is prescribed.
    pub fn new(mesh: &HighOrderMesh) -> DofMap {
        DofMap::numbered(mesh, |_| false, None)
    }

    /// As [`DofMap::new`], with the cell-interior nodes statically condensed
    /// ([`condense`](self::condense)); the same as `new` where cells have no
    /// interior node (below order 3 in 2D, 4 in 3D).
    pub fn condensed(mesh: &HighOrderMesh) -> DofMap {
        let split = LocalSplit::new(mesh);
        if split.interior.is_empty() {
            return DofMap::new(mesh);
        }
        let dim = mesh.dim();
        let mut interior = vec![false; mesh.n_nodes()];
        for c in 0..mesh.n_cells() {
            let cell = mesh.cell(c);
            for l in split.interior.iter().step_by(dim) {
                interior[cell[l / dim]] = true;
            }
        }
        if (0..mesh.n_nodes()).any(|n| interior[n] && mesh.constraint[n] != NodeConstraint::Free) {
            return DofMap::new(mesh); // not a mesh from elevation: leave it whole
        }
        DofMap::numbered(mesh, |n| interior[n], Some(split))
    }

    /// Free nodes for which `last(node)` is false first, then the others.
    fn numbered(mesh: &HighOrderMesh, last: impl Fn(usize) -> bool, split: Option<LocalSplit>) -> DofMap {
        let dim = mesh.dim();
        let mut free = vec![usize::MAX; mesh.n_nodes() * dim];
        let mut n_free = 0;
        let mut n_system = 0;
        let order = locality_order(mesh);
        for pass in [false, true] {
            for &n in &order {
                if mesh.constraint[n] == NodeConstraint::Free && last(n) == pass {
                    for d in 0..dim {
                        free[n * dim + d] = n_free;
                        n_free += 1;
                    }
                }
            }
            if !pass {
                n_system = n_free;
            }
        }
        DofMap { dim, free, n_free, n_system, split }
    }

    /// What `dof` is: prescribed, a system unknown, or a condensed interior one.
    #[inline]
    pub fn role(&self, dof: usize) -> DofRole {
        match self.free[dof] {
            usize::MAX => DofRole::Prescribed,
            f if f < self.n_system => DofRole::System(f),
            f => DofRole::Interior(f),
        }
    }

    /// The index of `dof` among the free dofs (system, then interior), or
    /// None when it is prescribed.
    #[inline]
    pub fn free_index(&self, dof: usize) -> Option<usize> {
        Some(self.free[dof]).filter(|&f| f != usize::MAX)
    }

    /// The row of `dof` in the assembled system, or None when it is
    /// prescribed or condensed.
    #[inline]
    pub fn system_row(&self, dof: usize) -> Option<usize> {
        Some(self.free[dof]).filter(|&f| f < self.n_system)
    }

    /// Move the geometry `x` (one value per dof) by a solution: `u` (on the
    /// free dofs) at the free dofs, and `prescribed` (one value per dof) at
    /// the prescribed ones, which are left alone when it is None.
    pub fn add_to(&self, x: &mut [f64], u: &[f64], prescribed: Option<&[f64]>) {
        const DOFS: usize = 8192;
        x.par_chunks_mut(DOFS).enumerate().for_each(|(k, xc)| {
            for (dof, x) in (k * DOFS..).zip(xc) {
                match (self.free_index(dof), prescribed) {
                    (Some(f), _) => *x += u[f],
                    (None, Some(p)) => *x += p[dof],
                    (None, None) => {}
                }
            }
        });
    }

    /// Whether the cell-interior dofs are condensed out of the system.
    pub fn is_condensed(&self) -> bool {
        self.split.is_some()
    }

    /// Lower-triangular CSC pattern of the system (the first `n_system` free
    /// dofs): (r, c) is present when the nodes of dofs r and c share a cell.
    /// Built in O(cells · nodes_per_cell²). Panics above 2^32 − 1 unknowns
    /// (32-bit row indices; such a mesh would need over 100 GB before its matrix).
    pub fn pattern(&self, mesh: &HighOrderMesh) -> SymmetricCsc {
        self.pattern_with_nodes(mesh).0
    }

    /// [`DofMap::pattern`] and its nodal-block layout, as the iterative
    /// solver would read it back from the pattern: per system
    /// node J (the `dim` rows from J·dim), the system nodes I ≥ J that share
    /// a cell with it, ascending, J first. A node's dofs are all free or
    /// all prescribed, and numbered one after another, so the pattern is
    /// always in that layout. Reading it back took 18–24 ms of a one-increment
    /// torus cavity run at p = 4.
    pub fn pattern_with_nodes(&self, mesh: &HighOrderMesh) -> (SymmetricCsc, Vec<Vec<u32>>) {
        assert!(self.n_system < u32::MAX as usize, "{} unknowns: more than 32-bit row indices hold", self.n_system);
        let n_nodes = mesh.n_nodes();
        let (start, node_cells) = node_cells(mesh);
        let dim = self.dim;
        let system_node = |n: usize| self.system_row(n * dim).map(|r| (r / dim) as u32);
        // Per free node: its system node index and those of its neighbours
        // from its own on, ascending (sorted as plain integers, not by a
        // looked-up key: 35 ms against 54 ms on the sphere cavity at p = 4).
        // The nodes of one edge, face or cell interior lie in the same cells
        // and are numbered one after another: their neighbours are gathered
        // once per run of such nodes (25,527 runs of 63,491 nodes on the
        // torus cavity at p = 4: 20-22 ms against 37-58 ms).
        let cells_of = |n: usize| &node_cells[start[n]..start[n + 1]];
        let mut runs: Vec<usize> = (0..n_nodes).filter(|&n| n == 0 || cells_of(n) != cells_of(n - 1)).collect();
        runs.push(n_nodes);
        let columns: Vec<Vec<u32>> = runs
            .par_windows(2)
            .flat_map_iter(|run| {
                let nodes = run[0]..run[1];
                let lowest = nodes.clone().filter_map(system_node).min().unwrap_or(u32::MAX);
                let mut nb: Vec<u32> = cells_of(run[0])
                    .iter()
                    .flat_map(|&c| mesh.cell(c).iter().filter_map(|&m| system_node(m)))
                    .filter(|&r| r >= lowest)
                    .collect();
                nb.sort_unstable();
                nb.dedup();
                nodes.map(move |n| match system_node(n) {
                    Some(own) => nb[nb.partition_point(|&r| r < own)..].to_vec(),
                    None => Vec::new(),
                })
            })
            .collect();
        // Per system node, in order (each list starts with its own).
        let mut nodes: Vec<Vec<u32>> = columns.into_iter().filter(|nb| !nb.is_empty()).collect();
        nodes.par_sort_unstable_by_key(|nb| nb[0]);
        // Column (J, c) holds rows (J, c..dim), then (I, 0..dim) of each
        // later neighbour I. Allocated to its length (grown by pushing, its
        // capacity was 1.5 times that on the bench's 3D p = 4 case: 200
        // bytes per unknown held through the whole solve) and filled node
        // by node in parallel (serially, 2 ms of a 31,000-unknown p = 2
        // system, on the critical path).
        let mut col_ptr = Vec::with_capacity(self.n_system + 1);
        let mut node_ptr = Vec::with_capacity(nodes.len() + 1);
        col_ptr.push(0);
        node_ptr.push(0);
        for nb in &nodes {
            for c in 0..dim {
                col_ptr.push(col_ptr[col_ptr.len() - 1] + (nb.len() - 1) * dim + dim - c);
            }
            node_ptr.push(col_ptr[col_ptr.len() - 1]);
        }
        let mut row_idx = vec![0u32; col_ptr[col_ptr.len() - 1]];
        let dim32 = dim as u32;
        crate::sparse::split_by(&mut row_idx, &node_ptr, 1).into_par_iter().zip(&nodes).for_each(|(out, nb)| {
            let mut k = 0;
            for c in 0..dim32 {
                for (t, &node) in nb.iter().enumerate() {
                    let d0 = if t == 0 { c } else { 0 };
                    for d in d0..dim32 {
                        out[k] = node * dim32 + d;
                        k += 1;
                    }
                }
            }
        });
        (SymmetricCsc { n: self.n_system, col_ptr, row_idx }, nodes)
    }
}

/// The cells around each node, in compressed rows: those of node n are
/// `cells[start[n]..start[n + 1]]`, ascending.
fn node_cells(mesh: &HighOrderMesh) -> (Vec<usize>, Vec<usize>) {
    cells_around(mesh, mesh.nodes_per_cell(), mesh.n_nodes())
}

/// The cells around each vertex, in compressed rows: those of vertex v are
/// `cells[start[v]..start[v + 1]]`, ascending.
fn vertex_cells(mesh: &HighOrderMesh) -> (Vec<usize>, Vec<usize>) {
    cells_around(mesh, mesh.dim() + 1, mesh.n_vertices)
}

/// The cells around each of the first `count` nodes, from the first `first`
/// nodes of each cell (the vertices come first in a cell, and in the mesh).
fn cells_around(mesh: &HighOrderMesh, first: usize, count: usize) -> (Vec<usize>, Vec<usize>) {
    let mut start = vec![0usize; count + 1];
    for c in 0..mesh.n_cells() {
        for &n in &mesh.cell(c)[..first] {
            start[n + 1] += 1;
        }
    }
    for i in 0..count {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut cells = vec![0usize; start[count]];
    for c in 0..mesh.n_cells() {
        for &n in &mesh.cell(c)[..first] {
            cells[fill[n]] = c;
            fill[n] += 1;
        }
    }
    (start, cells)
}

/// The mesh's nodes in an order that keeps the nodes of neighbouring cells
/// near one another, whatever the input's numbering: the cells in
/// breadth-first order through shared vertices (from cell 0, then from the
/// first cell not reached), each cell's nodes taken as first met; nodes of
/// no cell last. It depends on the cells only, so meshes with the same
/// cells get the same numbering and pattern. The mesh's own numbering puts
/// the vertices first, then the edges' nodes, the faces' and the cells':
/// a node's neighbours sat in four distant ranges. On the sphere cavity at
/// p = 4 (68k unknowns) the double-precision product, which reads the
/// lower triangle in place, took 15.6 ms with it and 10.2 ms with this order.
fn locality_order(mesh: &HighOrderMesh) -> Vec<usize> {
    let (start, vcells) = vertex_cells(mesh);
    let mut seen = vec![false; mesh.n_nodes()];
    let mut order = Vec::with_capacity(mesh.n_nodes());
    for c in breadth_first_cells(mesh, &start, &vcells) {
        for &n in mesh.cell(c) {
            if !seen[n] {
                seen[n] = true;
                order.push(n);
            }
        }
    }
    order.extend((0..mesh.n_nodes()).filter(|&n| !seen[n]));
    order
}

/// The cells in breadth-first order through shared vertices (`start`,
/// `vcells`: [`vertex_cells`]), each connected part from its lowest cell.
fn breadth_first_cells(mesh: &HighOrderMesh, start: &[usize], vcells: &[usize]) -> Vec<usize> {
    let (nv, nc) = (mesh.dim() + 1, mesh.n_cells());
    let mut reached = vec![false; nc];
    let mut queue = Vec::with_capacity(nc);
    for seed in 0..nc {
        if reached[seed] {
            continue;
        }
        reached[seed] = true;
        let mut head = queue.len();
        queue.push(seed);
        while head < queue.len() {
            let c = queue[head];
            head += 1;
            for &v in &mesh.cell(c)[..nv] {
                for &d in &vcells[start[v]..start[v + 1]] {
                    if !reached[d] {
                        reached[d] = true;
                        queue.push(d);
                    }
                }
            }
        }
    }
    queue
}

/// Cells per patch of the assembly ([`color_patches`]). On the built-in
/// 1.16M-unknown case at p = 4 (36,864 cells), five assemblies took 9.0 s
/// with cells coloured one by one and 6.6 s with patches of 64; on the
/// sphere cavity (2,685 cells), the scatter's thread time fell from 63–87
/// ms to 50 ms with patches of 128, but fewer patches per colour balance
/// the two threads worse.
const PATCH_CELLS: usize = 64;

/// The cells in patches of `patch_cells` consecutive cells of the
/// breadth-first order, the patches greedily coloured so that patches of
/// one colour share no vertex (the first `dim + 1` nodes of each cell):
/// colours, their patches, each patch's cells. A thread scatters a patch's
/// cells one after the other, so neighbouring cells, whose entries share
/// the matrix's cache lines, follow each other; with cells coloured one by
/// one, neighbours were always a colour apart. O(cells · neighbours).
pub fn color_patches(mesh: &HighOrderMesh, patch_cells: usize) -> Vec<Vec<Vec<usize>>> {
    let nv = mesh.dim() + 1;
    let (start, vcells) = vertex_cells(mesh);
    let order = breadth_first_cells(mesh, &start, &vcells);
    let patches: Vec<&[usize]> = order.chunks(patch_cells.max(1)).collect();
    let mut patch_of = vec![0; mesh.n_cells()];
    for (p, cells) in patches.iter().enumerate() {
        for &c in cells.iter() {
            patch_of[c] = p;
        }
    }
    let mut color = vec![usize::MAX; patches.len()];
    let mut stamp: Vec<usize> = Vec::new();
    let mut groups: Vec<Vec<Vec<usize>>> = Vec::new();
    for (p, cells) in patches.iter().enumerate() {
        for &c in cells.iter() {
            for &v in &mesh.cell(c)[..nv] {
                for &c2 in &vcells[start[v]..start[v + 1]] {
                    if color[patch_of[c2]] != usize::MAX {
                        stamp[color[patch_of[c2]]] = p;
                    }
                }
            }
        }
        let k = (0..stamp.len()).find(|&k| stamp[k] != p).unwrap_or(stamp.len());
        if k == stamp.len() {
            stamp.push(usize::MAX);
            groups.push(Vec::new());
        }
        color[p] = k;
        groups[k].push(cells.to_vec());
    }
    groups
}

/// What every assembly on one mesh and pattern shares: the coloured patches
/// of cells ([`color_patches`]) and, per cell and pair of its nodes (a, b) whose rows
/// are in the system with row(a) > row(b), the offset of row (node(a), 0)
/// within column (node(b), 0) of the pattern, so that no assembly searches
/// the pattern.
/// One 4-byte offset per unordered pair of cell nodes ([`pair_index`]):
/// 2.3 kB per cell at p = 4 in 3D.
#[derive(Debug, Clone)]
struct AssemblyPlan {
    colors: Vec<Vec<Vec<usize>>>,
    pairs: usize,
    offsets: Vec<u32>,
}

/// The place of the unordered pair {a, b} (a ≠ b) of a cell's local nodes
/// among its npc(npc − 1)/2 pairs.
#[inline]
fn pair_index(a: usize, b: usize) -> usize {
    let (hi, lo) = if a > b { (a, b) } else { (b, a) };
    hi * (hi - 1) / 2 + lo
}

impl AssemblyPlan {
    fn new(mesh: &HighOrderMesh, dofs: &DofMap, pattern: &SymmetricCsc) -> AssemblyPlan {
        let (dim, npc) = (mesh.dim(), mesh.nodes_per_cell());
        let pairs = npc * (npc - 1) / 2;
        let mut offsets = vec![u32::MAX; mesh.n_cells() * pairs];
        // Per cell, its system nodes in the order of their rows; the column
        // of each (its first dof's) lists the node's own `dim` rows, then
        // `dim` rows of each later coupled node, ascending: one walk down it
        // finds the later nodes of the cell in turn. (A binary search per
        // pair took 30 and 55-70 ms on the sphere and torus cavities at p = 4.)
        offsets.par_chunks_mut(pairs.max(1)).enumerate().for_each_init(Vec::new, |sorted, (c, out)| {
            let cell = mesh.cell(c);
            sorted.clear();
            sorted.extend(cell.iter().enumerate().filter_map(|(a, &n)| dofs.system_row(n * dim).map(|r| (r, a))));
            sorted.sort_unstable();
            for (t, &(s0, cb)) in sorted.iter().enumerate() {
                let column = &pattern.row_idx[pattern.col_ptr[s0]..pattern.col_ptr[s0 + 1]];
                let mut k = dim;
                for &(r0, ra) in &sorted[t + 1..] {
                    while column.get(k).expect("pattern covers every cell coupling") != &(r0 as u32) {
                        k += dim;
                    }
                    out[pair_index(ra, cb)] = k as u32;
                }
            }
        });
        AssemblyPlan { colors: color_patches(mesh, PATCH_CELLS), pairs, offsets }
    }

    #[inline]
    fn cell_offsets(&self, c: usize) -> &[u32] {
        &self.offsets[c * self.pairs..(c + 1) * self.pairs]
    }
}

/// Add `v` to a slot that no other thread touches during this colour.
#[inline]
fn add(slot: &AtomicU64, v: f64) {
    slot.store((f64::from_bits(slot.load(Ordering::Relaxed)) + v).to_bits(), Ordering::Relaxed);
}

/// An element operator: the element matrix and, optionally, the element
/// internal-force vector, on the element's current node coordinates.
pub trait ElementKernel: Sync {
    type Workspace: Send;
    fn workspace(&self) -> Self::Workspace;
    /// Fill `ke` (row-major, dof (a, i) = a·dim + i) and, when given, `re`
    /// (internal forces ∫ σ : ∇N_a) for cell `cell` with node coordinates
    /// `xe`. Returns `Err(det J)` if the element is inverted at a point.
    fn compute(
        &self,
        cell: usize,
        xe: &[f64],
        ke: &mut [f64],
        re: Option<&mut [f64]>,
        ws: &mut Self::Workspace,
    ) -> std::result::Result<(), f64>;
    /// The linear elastic kernel itself, when this is it: its operator can
    /// be applied cell by cell without the matrix ([`System::cell_operator`]).
    fn cell_kernel(&self) -> Option<&LinearElasticKernel> {
        None
    }
    /// The material, when this is the linear elastic kernel of
    /// [`LinearElasticKernel::for_nodes`] (which a distributed elastic
    /// stage builds again on each process).
    fn linear_material(&self) -> Option<crate::material::LinearElastic> {
        None
    }
}

/// The element's right-hand side b = −re − K_ed u_d at every local dof (the
/// prescribed values `prescribed` of the cell's prescribed nodes; `re` zero
/// when not given). Entries of prescribed rows are computed and unused.
fn element_rhs(
    cell: &[usize],
    dim: usize,
    dofs: &DofMap,
    ke: &[f64],
    re: Option<&[f64]>,
    prescribed: &[f64],
    b: &mut [f64],
) {
    let ndof_e = cell.len() * dim;
    match re {
        Some(re) => b.iter_mut().zip(re).for_each(|(b, r)| *b = -r),
        None => b.fill(0.0),
    }
    for (cb, &nb) in cell.iter().enumerate() {
        if dofs.free_index(nb * dim).is_some() {
            continue;
        }
        for j in 0..dim {
            let u = prescribed[nb * dim + j];
            if u != 0.0 {
                for (k, bk) in b.iter_mut().enumerate() {
                    *bk -= ke[k * ndof_e + cb * dim + j] * u;
                }
            }
        }
    }
}

/// The global lower triangle and right-hand side as the scatter sees them:
/// atomics, each slot written by one thread per colour.
struct Target<'a> {
    dofs: &'a DofMap,
    pattern: &'a SymmetricCsc,
    values: &'a [AtomicU64],
    rhs: &'a [AtomicU64],
}

impl Target<'_> {
    /// Add one element's matrix `ke` and right-hand side `b`
    /// ([`element_rhs`]) at its system rows. `offsets` are the cell's from
    /// [`AssemblyPlan`]; within a pair's 3×3 (2×2) block the positions follow
    /// from the layout of [`DofMap::pattern`] (column (n, j) lists node n's
    /// components j.. then each later node's components in order, so the
    /// block of node m > n sits j places earlier in column (n, j) than in
    /// column (n, 0)). `slots`: the cell's rows and column starts
    /// ([`CellSlots::locate`]).
    #[inline]
    fn add_cell(&self, cell: &[usize], offsets: &[u32], ke: &[f64], b: &[f64], slots: &CellSlots) {
        match self.dofs.dim {
            2 => self.add_cell_in::<2>(cell, offsets, ke, b, slots),
            _ => self.add_cell_in::<3>(cell, offsets, ke, b, slots),
        }
    }

    /// [`Self::add_cell`] in dimension `D`: a pair's block is `D` runs of
    /// `D` slots, each found once, its loops unrolled.
    #[inline(always)]
    fn add_cell_in<const D: usize>(&self, cell: &[usize], offsets: &[u32], ke: &[f64], b: &[f64], slots: &CellSlots) {
        let pattern = self.pattern;
        let ndof_e = cell.len() * D;
        let CellSlots { rows, starts } = slots;
        for (ra, &r0) in rows.iter().enumerate() {
            if r0 == usize::MAX {
                continue;
            }
            // Rows (na, 0..D) of the element matrix.
            let ke_a: [&[f64]; D] = std::array::from_fn(|i| &ke[(ra * D + i) * ndof_e..][..ndof_e]);
            for (cb, &s0) in rows.iter().enumerate() {
                if s0 > r0 {
                    continue;
                }
                if ra == cb {
                    for j in 0..D {
                        let start = starts[cb * D + j] - j;
                        for i in j..D {
                            debug_assert_eq!(pattern.row_idx[start + i] as usize, r0 + i);
                            add(&self.values[start + i], ke_a[i][cb * D + j]);
                        }
                    }
                    continue;
                }
                // Offset of row (na, 0) within column (nb, 0).
                let offset = offsets[pair_index(ra, cb)] as usize;
                // The block K_(a i)(b j), row by row.
                let block: [&[f64; D]; D] =
                    std::array::from_fn(|i| ke_a[i][cb * D..][..D].try_into().expect("D columns"));
                for j in 0..D {
                    let start = starts[cb * D + j] + offset - j;
                    let slots: &[AtomicU64; D] = self.values[start..start + D].try_into().expect("D slots");
                    for (i, slot) in slots.iter().enumerate() {
                        debug_assert_eq!(pattern.row_idx[start + i] as usize, r0 + i);
                        add(slot, block[i][j]);
                    }
                }
            }
            for (i, &bi) in b[ra * D..(ra + 1) * D].iter().enumerate() {
                if bi != 0.0 {
                    add(&self.rhs[r0 + i], bi);
                }
            }
        }
    }
}

/// Scratch space of [`Target::add_cell`]: per node of the cell, its system
/// row (usize::MAX when prescribed or condensed, which no row is below) and
/// the starts of its columns in the pattern.
#[derive(Debug, Default)]
struct CellSlots {
    rows: Vec<usize>,
    starts: Vec<usize>,
}

impl CellSlots {
    /// The rows and column starts of `cell`'s nodes; then, on x86-64, a
    /// prefetch of every cache line its block pairs will be added to, which
    /// the element kernel's computation gives the time to arrive.
    #[inline]
    fn locate(&mut self, target: &Target, cell: &[usize], offsets: &[u32]) {
        let (dofs, pattern, dim) = (target.dofs, target.pattern, target.dofs.dim);
        self.rows.clear();
        self.starts.clear();
        for &n in cell {
            let row = dofs.system_row(n * dim);
            self.rows.push(row.unwrap_or(usize::MAX));
            self.starts.extend((0..dim).map(|j| row.map_or(0, |r| pattern.col_ptr[r + j])));
        }
        #[cfg(target_arch = "x86_64")]
        for (ra, &r0) in self.rows.iter().enumerate() {
            if r0 == usize::MAX {
                continue;
            }
            for (cb, &s0) in self.rows.iter().enumerate() {
                if s0 <= r0 {
                    let offset = if ra == cb { 0 } else { offsets[pair_index(ra, cb)] as usize };
                    for j in 0..dim {
                        let at = target.values.as_ptr().wrapping_add(self.starts[cb * dim + j] + offset - j);
                        // SAFETY: a prefetch is only a hint; it reads nothing.
                        unsafe { std::arch::x86_64::_mm_prefetch(at.cast::<i8>(), std::arch::x86_64::_MM_HINT_T1) };
                    }
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = offsets;
    }
}

/// The linear system of one mesh and everything that assembles it: the dof
/// numbering with each dof's role, the lower-triangular pattern, the
/// assembly plan, and the assembled values, right-hand side and (with static
/// condensation) what recovers the interior unknowns after a solve.
///
/// [`System::assemble`] reuses the buffers of the previous assembly: a fresh
/// system per increment cost 6–11 % of a ten-increment run in page faults
/// and zeroing.
#[derive(Debug, Clone)]
pub struct System {
    dofs: DofMap,
    pattern: SymmetricCsc,
    plan: AssemblyPlan,
    values: Vec<f64>,
    rhs: Vec<f64>,
    rhs_norm: f64,
    interior: Option<InteriorRecovery>,
    /// With condensation and `residual`: the uncondensed b on the system rows
    /// and ‖b_I‖² per cell, for `rhs_norm`.
    full_rhs: Vec<f64>,
    interior_sq: Vec<f64>,
    /// Where the cells' values go in products from the cells, once found.
    cell_layout: Option<std::sync::Arc<matrix_free::CellLayout>>,
    /// The buffers of the last cell operator handed back, for the next.
    spare_operator: Option<matrix_free::CellOperator>,
}

impl System {
    /// The pattern and plan of `dofs` on `mesh`, nothing assembled yet.
    pub fn new(mesh: &HighOrderMesh, dofs: DofMap) -> System {
        Self::with_nodes(mesh, dofs).0
    }

    /// [`System::new`], and the pattern's nodal-block layout
    /// ([`DofMap::pattern_with_nodes`]) for the iterative solver.
    pub fn with_nodes(mesh: &HighOrderMesh, dofs: DofMap) -> (System, Vec<Vec<u32>>) {
        let (pattern, nodes) = dofs.pattern_with_nodes(mesh);
        let plan = AssemblyPlan::new(mesh, &dofs, &pattern);
        let system = System {
            dofs,
            pattern,
            plan,
            values: Vec::new(),
            rhs: Vec::new(),
            rhs_norm: 0.0,
            interior: None,
            full_rhs: Vec::new(),
            interior_sq: Vec::new(),
            cell_layout: None,
            spare_operator: None,
        };
        (system, nodes)
    }

    /// The dof map, the pattern and the assembled values.
    pub fn into_matrix(self) -> (DofMap, SymmetricCsc, Vec<f64>) {
        (self.dofs, self.pattern, self.values)
    }

    /// Free the assembled values (a solve from the cells' products does not
    /// read them); the next assembly allocates them again.
    pub fn release_values(&mut self) {
        self.values = Vec::new();
    }

    pub fn dofs(&self) -> &DofMap {
        &self.dofs
    }

    /// The lower-triangular pattern of the system ([`DofMap::pattern`]).
    pub fn pattern(&self) -> &SymmetricCsc {
        &self.pattern
    }

    /// The values of the lower triangle on [`System::pattern`].
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// The right-hand side on the system rows.
    pub fn rhs(&self) -> &[f64] {
        &self.rhs
    }

    /// ‖b_f‖ over every free dof of the uncondensed system when assembled
    /// with `residual` (the Newton residual; with condensation it is not
    /// ‖rhs‖), else ‖rhs‖.
    pub fn rhs_norm(&self) -> f64 {
        self.rhs_norm
    }

    /// Complete a solution `u` of the system (its first `n_system` entries)
    /// with the condensed interior unknowns; `prescribed` as given to
    /// [`System::assemble`]. Nothing to do without condensation.
    pub fn recover_interior(&self, mesh: &HighOrderMesh, prescribed: &[f64], u: &mut [f64]) {
        if let Some(r) = &self.interior {
            r.recover(mesh, &self.dofs, prescribed, u);
        }
    }

    /// Assemble K_ff and the right-hand side b_f = −K_fd u_d − R_f on the
    /// geometry `coords`, where R is the internal force when `residual` is
    /// set (IIL, CIL, Newton) and zero otherwise (ILE); with condensation,
    /// the Schur complement on the system dofs.
    ///
    /// `prescribed[dof]` is the Dirichlet value of each prescribed dof
    /// (ignored for free dofs). Fails if an element has a non-positive
    /// Jacobian somewhere, or a singular interior block.
    pub fn assemble<K: ElementKernel>(
        &mut self,
        mesh: &HighOrderMesh,
        coords: &[f64],
        kernel: &K,
        prescribed: &[f64],
        residual: bool,
    ) -> Result<()> {
        let (dim, ndof_e) = (mesh.dim(), mesh.nodes_per_cell() * mesh.dim());
        let mut interior = self.take_interior();
        let dofs = &self.dofs;
        let split = dofs.split.as_ref();
        let stride = split.map_or(0, LocalSplit::stride);
        // With condensation, the Newton residual is still measured on every
        // free dof: the uncondensed b on the system rows, and ‖b_I‖² per cell.
        let measure = residual && split.is_some();
        let mut none = Vec::new();
        let keep = zeroed_atomics(interior.as_mut().map_or(&mut none, |r| &mut r.keep), stride * mesh.n_cells());
        let target = Target {
            dofs,
            pattern: &self.pattern,
            values: zeroed_atomics(&mut self.values, self.pattern.nnz()),
            rhs: zeroed_atomics(&mut self.rhs, dofs.n_system),
        };
        let full_rhs = zeroed_atomics(&mut self.full_rhs, if measure { dofs.n_system } else { 0 });
        let interior_sq = zeroed_atomics(&mut self.interior_sq, if measure { mesh.n_cells() } else { 0 });
        let init = || {
            let buffers = (vec![0.0; ndof_e * ndof_e], vec![0.0; ndof_e], vec![0.0; ndof_e], vec![0.0; stride]);
            (buffers, vec![0.0; ndof_e], kernel.workspace(), CondenseWorkspace::default(), CellSlots::default())
        };
        type Scratch<W> = ((Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>), Vec<f64>, W, CondenseWorkspace, CellSlots);
        let one_cell = |((ke, re, xe, kept), b, ws, cws, slots): &mut Scratch<K::Workspace>, c: usize| -> Result<()> {
                    let cell = mesh.cell(c);
                    slots.locate(&target, cell, self.plan.cell_offsets(c));
                    for (a, &n) in cell.iter().enumerate() {
                        xe[a * dim..(a + 1) * dim].copy_from_slice(&coords[n * dim..(n + 1) * dim]);
                    }
                    kernel.compute(c, xe, ke, if residual { Some(&mut re[..]) } else { None }, ws).map_err(
                        |det_j| {
                            Error::invalid_element(
                                Some(c),
                                format!("cell {c} has a non-positive Jacobian ({det_j:.3e})"),
                            )
                        },
                    )?;
                    if let Some(split) = split {
                        if measure {
                            element_rhs(cell, dim, dofs, ke, Some(re), prescribed, b);
                            let sq = scatter_full_residual(cell, dofs, b, full_rhs);
                            interior_sq[c].store(sq.to_bits(), Ordering::Relaxed);
                        }
                        condense_element(split, ke, residual.then_some(&mut re[..]), kept, cws).map_err(|_| {
                            Error::invalid_element(
                                Some(c),
                                format!("cell {c}: the stiffness of its interior nodes is singular"),
                            )
                        })?;
                        for (slot, v) in keep[c * stride..(c + 1) * stride].iter().zip(kept.iter()) {
                            slot.store(v.to_bits(), Ordering::Relaxed);
                        }
                    }
                    element_rhs(cell, dim, dofs, ke, residual.then_some(&re[..]), prescribed, b);
                    target.add_cell(cell, self.plan.cell_offsets(c), ke, b, slots);
                    Ok(())
        };
        for group in &self.plan.colors {
            group.par_iter().try_for_each_init(init, |scratch, patch| patch.iter().try_for_each(|&c| one_cell(scratch, c)))?;
        }
        self.rhs_norm = if measure {
            (self.full_rhs.iter().map(|v| v * v).sum::<f64>() + self.interior_sq.iter().sum::<f64>()).sqrt()
        } else {
            self.rhs.iter().map(|v| v * v).sum::<f64>().sqrt()
        };
        self.interior = interior;
        Ok(())
    }

    /// The interior recovery of the last assembly or cell operator (its
    /// buffer reused, for cells in the mesh's order), or a new one; None
    /// without condensation.
    fn take_interior(&mut self) -> Option<InteriorRecovery> {
        match (self.dofs.split.as_ref(), self.interior.take()) {
            (Some(split), Some(r)) if r.split == *split => Some(InteriorRecovery { order: None, ..r }),
            (Some(split), _) => Some(InteriorRecovery { split: split.clone(), keep: Vec::new(), order: None }),
            (None, _) => None,
        }
    }
}

/// One cell's uncondensed right-hand side `b` added to `full_rhs` at its
/// system rows; returns ‖b‖² over its condensed interior dofs (the parts of
/// the Newton residual that the condensed system does not hold).
fn scatter_full_residual(cell: &[usize], dofs: &DofMap, b: &[f64], full_rhs: &[AtomicU64]) -> f64 {
    let dim = dofs.dim;
    let mut sq = 0.0;
    for (k, &bk) in b.iter().enumerate() {
        match dofs.role(cell[k / dim] * dim + k % dim) {
            DofRole::Prescribed => {}
            DofRole::System(f) => add(&full_rhs[f], bk),
            DofRole::Interior(_) => sq += bk * bk,
        }
    }
    sq
}

/// `v` as `n` zeros written in parallel, seen as atomics for the lock-free
/// scatter. Without the room, `v` is allocated anew, so that its pages are
/// first touched by these writes, on every thread (at a million unknowns
/// the values are 0.9 GB: grown by `resize`, serially, the first assembly
/// took 0.3 s longer), and not by the scatter, whose first read of a
/// page and then its write each fault (1.5 s longer).
fn zeroed_atomics(v: &mut Vec<f64>, n: usize) -> &[AtomicU64] {
    const _: () = assert!(
        std::mem::size_of::<f64>() == std::mem::size_of::<AtomicU64>()
            && std::mem::align_of::<f64>() == std::mem::align_of::<AtomicU64>()
    );
    if v.capacity() < n {
        *v = Vec::new();
        *v = vec![0.0; n];
    }
    v.truncate(n);
    v.par_chunks_mut(1 << 16).for_each(|c| c.fill(0.0));
    v.resize(n, 0.0);
    // SAFETY: f64 and AtomicU64 have the same size and alignment (checked
    // above) and AtomicU64 has the in-memory representation of u64, of which
    // f64 is a bit-cast; the exclusive borrow of `v` outlives the view, so
    // nothing else reads or writes it meanwhile.
    unsafe { std::slice::from_raw_parts(v.as_mut_ptr().cast::<AtomicU64>(), n) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cases;
    use crate::mesh::{validate_and_orient, Topology};
    use crate::reference::{NodeSet, NodeSpacing};

    /// The built-in sphere cavity (`n` cells a side) elevated straight to order 2.
    fn sphere_at_order_2(n: usize) -> HighOrderMesh {
        let case = cases::sphere_in_box_3d(n, 2);
        let (lin, _) = validate_and_orient(&case.mesh).unwrap();
        let topo = Topology::new(&lin).unwrap();
        let nodes = NodeSet::new(topo.simplex, 2, NodeSpacing::Optimal);
        HighOrderMesh::elevate(&lin, &topo, &nodes, NodeSpacing::Optimal).unwrap()
    }

    #[test]
    fn the_locality_order_is_a_permutation_that_keeps_a_cells_nodes_near() {
        let mesh = sphere_at_order_2(3);
        let order = locality_order(&mesh);
        let mut seen = vec![false; mesh.n_nodes()];
        order.iter().for_each(|&n| seen[n] = true);
        assert!(seen.iter().all(|&s| s) && order.len() == mesh.n_nodes());
        // A cell's nodes span less of the order than of the mesh's own
        // numbering (vertices first, then edges).
        let mut place = vec![0; mesh.n_nodes()];
        order.iter().enumerate().for_each(|(k, &n)| place[n] = k);
        let spread = |at: &dyn Fn(usize) -> usize| -> usize {
            (0..mesh.n_cells())
                .map(|c| {
                    let k: Vec<usize> = mesh.cell(c).iter().map(|&n| at(n)).collect();
                    k.iter().max().unwrap() - k.iter().min().unwrap()
                })
                .sum()
        };
        let (ordered, natural) = (spread(&|n| place[n]), spread(&|n| n));
        assert!(2 * ordered < natural, "cell spread {ordered} in the order, {natural} in the mesh's numbering");
    }

    #[test]
    fn pair_index_numbers_the_unordered_pairs_of_a_cell_once_each() {
        for npc in [3, 10, 35] {
            let mut seen = vec![0; npc * (npc - 1) / 2];
            for a in 0..npc {
                for b in 0..npc {
                    if a != b {
                        assert_eq!(pair_index(a, b), pair_index(b, a));
                        seen[pair_index(a, b)] += 1;
                    }
                }
            }
            assert!(seen.iter().all(|&k| k == 2), "npc = {npc}");
        }
    }

    #[test]
    fn the_patches_cover_every_cell_once_and_no_colour_shares_a_node() {
        let mesh = sphere_at_order_2(2);
        for patch_cells in [1, 7, 32] {
            let colors = color_patches(&mesh, patch_cells);
            let mut seen = vec![0; mesh.n_cells()];
            for group in &colors {
                let mut used = std::collections::HashMap::new();
                for (p, patch) in group.iter().enumerate() {
                    assert!(!patch.is_empty() && patch.len() <= patch_cells);
                    for &c in patch {
                        seen[c] += 1;
                        for &n in mesh.cell(c) {
                            let owner = *used.entry(n).or_insert(p);
                            assert_eq!(owner, p, "node {n} in two patches of one colour");
                        }
                    }
                }
            }
            assert!(seen.iter().all(|&s| s == 1));
            assert!(colors.len() < 200, "{} colours", colors.len());
        }
    }

    #[test]
    fn the_pattern_couples_the_free_dofs_of_nodes_that_share_a_cell() {
        // Against a plain construction: every pair of free dofs (r ≥ c) of
        // nodes in one cell, per column in ascending rows; and its nodal
        // layout, the nodes of the rows of each node's first column.
        let mesh = sphere_at_order_2(2);
        let dofs = DofMap::new(&mesh);
        let mut columns = vec![std::collections::BTreeSet::new(); dofs.n_system];
        for cell in mesh.cells.chunks_exact(mesh.nodes_per_cell()) {
            for &a in cell {
                for &b in cell {
                    for (i, j) in (0..3).flat_map(|i| (0..3).map(move |j| (i, j))) {
                        if let (Some(r), Some(c)) = (dofs.system_row(a * 3 + i), dofs.system_row(b * 3 + j)) {
                            if r >= c {
                                columns[c].insert(r as u32);
                            }
                        }
                    }
                }
            }
        }
        let (pattern, nodes) = dofs.pattern_with_nodes(&mesh);
        assert_eq!(pattern.n, dofs.n_system);
        for (c, rows) in columns.iter().enumerate() {
            let got = &pattern.row_idx[pattern.col_ptr[c]..pattern.col_ptr[c + 1]];
            assert_eq!(got, rows.iter().copied().collect::<Vec<u32>>().as_slice(), "column {c}");
        }
        assert_eq!(pattern.col_ptr.len(), dofs.n_system + 1);
        assert_eq!(nodes.len() * 3, dofs.n_system);
        for (j, got) in nodes.iter().enumerate() {
            let mut want: Vec<u32> = columns[j * 3].iter().map(|r| r / 3).collect();
            want.dedup();
            assert_eq!(got, &want, "node {j}");
        }
    }

    #[test]
    fn parallel_assembly_is_bitwise_equal_to_serial() {
        use crate::mapping::ElementCache;
        use crate::material::LinearElastic;
        use crate::quadrature::simplex_rule;
        use crate::reference::LagrangeBasis;
        let mesh = sphere_at_order_2(3);
        let nodes = NodeSet::new(mesh.simplex, 2, NodeSpacing::Optimal);
        let cache = ElementCache::new(&LagrangeBasis::new(&nodes), &simplex_rule(mesh.simplex, 4));
        let kernel = LinearElasticKernel { cache, material: LinearElastic::try_from_young_poisson(1.0, 0.3).unwrap() };
        let prescribed: Vec<f64> = (0..mesh.coords.len()).map(|i| (i as f64 * 0.1).sin()).collect();
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut system = System::new(&mesh, DofMap::new(&mesh));
            pool.install(|| system.assemble(&mesh, &mesh.coords, &kernel, &prescribed, false)).unwrap();
            system
        };
        let serial = run(1);
        for _ in 0..3 {
            let par = run(4);
            assert!(
                serial.values() == par.values() && serial.rhs() == par.rhs(),
                "parallel assembly differs from serial"
            );
        }
        // And the matrix is the sum of element matrices: K·1 = 0 rows for interior nodes (rigid translation).
        let ones = vec![1.0; serial.pattern().n];
        let k1 = serial.pattern().sym_matvec(serial.values(), &ones);
        assert!(k1.iter().any(|v| v.abs() > 1e-12), "K is not trivially zero");
    }
}
