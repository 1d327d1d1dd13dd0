//! Curving across the processes of an MPI run (the `mpi` feature).
//!
//! The first process (rank 0) holds the mesh and runs the whole pipeline:
//! repair, elevation, placement of the boundary nodes, the optimisation,
//! certification and quality. Each elastic stage, where nearly all the
//! memory and time of a large run go (the assembled system and its
//! preconditioner), is split: rank 0 partitions the cells with METIS, sends
//! every process its cells with their nodes, and all processes run the
//! ordinary increment loop on their own cells ([`Parallel::Part`]). The
//! linear solves go through PETSc ([`petsc::PetscSystem`]: CG with a
//! two-level p-multigrid, AMG on its P1 level, on the matrix summed from
//! every process's cells), and every decision that must be the same
//! everywhere (step back, restart, stop, fail) is agreed through
//! [`MpiCollective`]. The processes then send their nodes' positions back
//! to rank 0.
//!
//! So the system (several KB per unknown at p = 4 in 3D) is spread over the
//! processes, while the mesh itself (about 160 bytes per unknown, measured)
//! stays whole on rank 0.

pub mod partitioned;
pub mod petsc;

use std::sync::{Arc, Mutex};

use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::assembly::{DofMap, LinearElasticKernel};
use crate::curve::{
    solve_increments_from, Collective, ElasticBackend, IncrementsReport, Parallel, Stage, Stepping, Timings,
};
use crate::geometry::Projector;
use crate::material::LinearElastic;
use crate::mesh::{HighOrderMesh, NodeConstraint};
use crate::reference::{NodeSet, NodeSpacing, Simplex};
use crate::solver::{CsrView, LowerCscView, SystemSolver};
use crate::solver::{ExternalSolver, SolverChoice};
use crate::sparse::SymmetricCsc;
use crate::{Error, Result, SolverFailure};

/// PCG's relative tolerance, as the built-in iterative solver's.
const RTOL: f64 = 1e-5;

/// Integers before the arrays of a part's message ([`Part::encode`]).
const HEAD: usize = 17;

/// Commands rank 0 broadcasts to the others: the command, and the rank
/// that is to answer a projection request.
const STOP: u64 = 0;
const SOLVE: u64 = 1;
const PROJECT: u64 = 2;

/// `MPI_COMM_WORLD`, shared by the objects of one run. MPI is initialised
/// with one thread: every call comes from the thread that runs the curving.
struct World(SimpleCommunicator);
// SAFETY: see `World`: the communicator is used from one thread only.
unsafe impl Send for World {}
unsafe impl Sync for World {}

/// Rank 0's side: the backend of [`Parallel::Lead`].
pub struct Lead {
    world: World,
}

impl Lead {
    /// The backend for `world`, whose other ranks run [`serve`].
    pub fn new(world: SimpleCommunicator) -> Lead {
        Lead { world: World(world) }
    }

    /// The options' setting that hands every elastic stage to this backend.
    pub fn parallel(self: &Arc<Self>) -> Parallel {
        Parallel::Lead(self.clone())
    }

    /// Number of processes.
    pub fn size(&self) -> usize {
        self.world.0.size() as usize
    }

    /// Let the other ranks' [`serve`] return.
    pub fn stop(&self) {
        self.command(STOP, 0);
    }

    fn command(&self, cmd: u64, rank: usize) {
        let mut cmd = [cmd, rank as u64];
        self.world.0.process_at_rank(0).broadcast_into(&mut cmd[..]);
    }

    /// Project `points` onto entity (`entity_dim`, `tag`) with the projector
    /// of process `rank` (> 0), which is in [`serve`].
    pub fn project_on(
        &self,
        rank: usize,
        entity_dim: usize,
        tag: i32,
        points: &[[f64; 3]],
        out: &mut [[f64; 3]],
    ) -> std::result::Result<(), String> {
        self.command(PROJECT, rank);
        let to = self.world.0.process_at_rank(rank as i32);
        to.send(&[entity_dim as u64, tag as i64 as u64][..]);
        to.send(points.as_flattened());
        let (reply, _) = to.receive_vec::<u8>();
        let (flat, _) = to.receive_vec::<f64>();
        if reply.first() != Some(&0) {
            return Err(format!("{} (on process {rank})", String::from_utf8_lossy(reply.get(1..).unwrap_or(&[]))));
        }
        if flat.len() != out.len() * 3 {
            return Err(format!("process {rank} sent {} coordinates for {} points", flat.len(), out.len()));
        }
        out.as_flattened_mut().copy_from_slice(&flat);
        Ok(())
    }
}

/// The other ranks' side: take part in every elastic stage rank 0 starts,
/// and answer its projection requests with `projector` (see
/// [`Lead::project_on`]), until it calls [`Lead::stop`].
pub fn serve(world: SimpleCommunicator, projector: Option<&dyn Projector>) -> Result<()> {
    let world = World(world);
    loop {
        let mut cmd = [0u64; 2];
        world.0.process_at_rank(0).broadcast_into(&mut cmd[..]);
        match cmd[0] {
            SOLVE => {}
            PROJECT if cmd[1] == world.0.rank() as u64 => {
                answer_projection(&world, projector);
                continue;
            }
            PROJECT => continue,
            _ => return Ok(()),
        }
        let (ints, floats) = receive(&world);
        let part = match Part::decode(&ints, &floats) {
            Ok(part) => part,
            Err(e) => {
                // Rank 0 is past the point of hearing back: end the whole run.
                eprintln!("error (rank {}): {e}", world.0.rank());
                world.0.abort(1);
            }
        };
        let mut timings = Timings::default();
        let outcome = part.solve(&world, &mut timings, &mut |_, _, _| Ok(()));
        if let Ok((mesh, report)) = outcome {
            send_back(&world, &part, &mesh, report.first_rate.as_deref());
        }
    }
}

/// Project the points rank 0 sends ([`Lead::project_on`]) and send back a
/// status (0 = done), the points, and the error message if any.
fn answer_projection(world: &World, projector: Option<&dyn Projector>) {
    let (ints, floats) = receive(world);
    let points: Vec<[f64; 3]> = floats.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
    let mut out = vec![[f64::NAN; 3]; points.len()];
    let result = match (projector, ints.as_slice()) {
        (Some(p), &[entity_dim, tag]) => p.project(entity_dim as usize, tag as i64 as i32, &points, &mut out),
        (None, _) => Err("this process has no projector".into()),
        _ => Err("a malformed projection request".into()),
    };
    let root = world.0.process_at_rank(0);
    // A status byte first: an empty buffer's address is OpenMPI's MPI_IN_PLACE.
    let mut reply = vec![result.is_err() as u8];
    reply.extend(result.err().unwrap_or_default().bytes());
    root.send(&reply[..]);
    root.send(out.as_flattened());
}

/// One process's share of an elastic stage.
struct Part {
    mesh: HighOrderMesh,
    material: LinearElastic,
    stepping: Stepping,
    /// Per local node: its index in the whole mesh, and whether this
    /// process owns it (returns its position).
    global_node: Vec<usize>,
    owned: Vec<bool>,
    /// Per local node: its row block in PETSc's numbering, if a system
    /// node, and its row block on the P1 level, if a free vertex.
    petsc_node: Vec<usize>,
    petsc_vertex: Vec<usize>,
    /// This process's row blocks on the P1 level, and their number in all.
    n_coarse_owned: usize,
    n_coarse_global: usize,
    global_cell: Vec<usize>,
    /// This process's rows of the distributed system, and their number in all.
    first_owned: usize,
    n_owned: usize,
    n_global: usize,
    ubar: Vec<f64>,
    /// Per local dof, the start's rate (NaN where none).
    rate: Option<Vec<f64>>,
}

/// The node spacing as an integer of a part's message.
fn spacing_code(s: NodeSpacing) -> u64 {
    match s {
        NodeSpacing::Equispaced => 0,
        NodeSpacing::Optimal => 1,
    }
}

impl Part {
    /// The message that carries this part to its process: integers, then floats.
    fn encode(&self) -> (Vec<u64>, Vec<f64>) {
        let m = &self.mesh;
        let s = &self.stepping;
        let mut ints = vec![
            m.dim() as u64,
            m.order as u64,
            spacing_code(m.spacing),
            s.condense as u64,
            s.increments as u64,
            s.adaptive as u64,
            s.max_splits as u64,
            s.finish as u64,
            self.rate.is_some() as u64,
            m.n_nodes() as u64,
            m.n_vertices as u64,
            m.n_cells() as u64,
            self.first_owned as u64,
            self.n_owned as u64,
            self.n_global as u64,
            self.n_coarse_owned as u64,
            self.n_coarse_global as u64,
        ];
        ints.extend(m.cells.iter().map(|&n| n as u64));
        ints.extend(self.global_node.iter().map(|&n| n as u64));
        ints.extend(self.owned.iter().map(|&o| o as u64));
        ints.extend(m.constraint.iter().map(|c| (*c != NodeConstraint::Free) as u64));
        ints.extend(self.petsc_node.iter().map(|&n| n as u64));
        ints.extend(self.petsc_vertex.iter().map(|&n| n as u64));
        ints.extend(self.global_cell.iter().map(|&c| c as u64));
        let mut floats = vec![self.material.lambda, self.material.mu];
        floats.extend_from_slice(&m.coords);
        floats.extend_from_slice(&self.ubar);
        if let Some(r) = &self.rate {
            floats.extend_from_slice(r);
        }
        (ints, floats)
    }

    fn decode(ints: &[u64], floats: &[f64]) -> Result<Part> {
        let bad = || Error::InvalidInput("distributed run: a malformed message from rank 0".into());
        let head = ints.get(..HEAD).ok_or_else(bad)?;
        let h = |i: usize| head[i] as usize;
        let simplex = Simplex::from_dim(h(0)).ok_or_else(bad)?;
        let (order, n_nodes, n_cells) = (h(1), h(9), h(11));
        let spacing = if h(2) == 0 { NodeSpacing::Equispaced } else { NodeSpacing::Optimal };
        let npc = simplex.n_nodes(order);
        let dim = simplex.dim();
        let mut at = HEAD;
        let mut take = |n: usize| -> Result<&[u64]> {
            let s = ints.get(at..at + n).ok_or_else(bad)?;
            at += n;
            Ok(s)
        };
        let cells: Vec<usize> = take(n_cells * npc)?.iter().map(|&v| v as usize).collect();
        let global_node: Vec<usize> = take(n_nodes)?.iter().map(|&v| v as usize).collect();
        let owned: Vec<bool> = take(n_nodes)?.iter().map(|&v| v != 0).collect();
        let constraint =
            take(n_nodes)?.iter().map(|&v| if v == 0 { NodeConstraint::Free } else { NodeConstraint::Fixed }).collect();
        let petsc_node: Vec<usize> = take(n_nodes)?.iter().map(|&v| v as usize).collect();
        let petsc_vertex: Vec<usize> = take(n_nodes)?.iter().map(|&v| v as usize).collect();
        let global_cell: Vec<usize> = take(n_cells)?.iter().map(|&v| v as usize).collect();
        let nd = n_nodes * dim;
        let want = 2 + 2 * nd + if h(8) != 0 { nd } else { 0 };
        if floats.len() != want || cells.iter().any(|&n| n >= n_nodes) {
            return Err(bad());
        }
        let mesh = HighOrderMesh {
            simplex,
            order,
            spacing,
            coords: floats[2..2 + nd].to_vec(),
            cells,
            n_vertices: h(10),
            constraint,
        };
        let stepping = Stepping {
            increments: h(4),
            residual: false,
            newton: None,
            solver: SolverChoice::Auto,
            direct_ordering: Default::default(),
            adaptive: h(5) != 0,
            max_splits: h(6),
            condense: h(3) != 0,
            finish: h(7) != 0,
            parallel: Parallel::Serial,
        };
        Ok(Part {
            mesh,
            material: LinearElastic { lambda: floats[0], mu: floats[1] },
            stepping,
            global_node,
            owned,
            petsc_node,
            petsc_vertex,
            n_coarse_owned: h(15),
            n_coarse_global: h(16),
            global_cell,
            first_owned: h(12),
            n_owned: h(13),
            n_global: h(14),
            ubar: floats[2 + nd..2 + 2 * nd].to_vec(),
            rate: (h(8) != 0).then(|| floats[2 + 2 * nd..].to_vec()),
        })
    }

    /// Run the increments on this part, with every other process.
    fn solve(
        &self,
        world: &World,
        timings: &mut Timings,
        tick: &mut dyn FnMut(Stage, usize, usize) -> Result<()>,
    ) -> Result<(HighOrderMesh, IncrementsReport)> {
        let mut mesh = self.mesh.clone();
        let dim = mesh.dim();
        let dofs = self.dofs(&mesh);
        // Global row of each local system row.
        let mut global = vec![0usize; dofs.n_system];
        let mut owned_coords = vec![0.0; self.n_owned];
        for n in 0..mesh.n_nodes() {
            for c in 0..dim {
                if let Some(r) = dofs.system_row(n * dim + c) {
                    let g = self.petsc_node[n] * dim + c;
                    global[r] = g;
                    if (self.first_owned..self.first_owned + self.n_owned).contains(&g) {
                        owned_coords[g - self.first_owned] = mesh.coords[n * dim + c];
                    }
                }
            }
        }
        let solver = PetscSolver {
            world: world.0.duplicate(),
            global,
            first_owned: self.first_owned,
            n_owned: self.n_owned,
            n_global: self.n_global,
            block: dim,
            owned_coords,
            coarse: Mutex::new(Some(self.coarse_level(&mesh, &dofs))),
            system: Mutex::new(None),
        };
        let collective = MpiCollective { world: world.0.duplicate(), global_cell: self.global_cell.clone() };
        let stepping = Stepping {
            solver: SolverChoice::External(ExternalSolver::new(solver)),
            parallel: Parallel::Part(Arc::new(collective)),
            ..self.stepping.clone()
        };
        let nodes = NodeSet::new(mesh.simplex, mesh.order, mesh.spacing);
        let kernel = LinearElasticKernel::for_nodes(&nodes, self.material);
        let rate: Option<Vec<f64>> = self.rate.as_ref().map(|r| by_free_index(&dofs, r));
        let result = solve_increments_from(&mut mesh, &kernel, &self.ubar, stepping, rate.as_deref(), timings, tick);
        // Every process ends the same way: the first error (by rank), if any.
        let local = result.as_ref().err().map(|e| (0, e.to_string()));
        let agreed = MpiCollective::first_on(&world.0, local);
        match (result, agreed) {
            (Ok(report), None) => Ok((mesh, report)),
            (Err(e), _) => Err(e),
            (Ok(_), Some((_, message))) => {
                Err(Error::solver(SolverFailure::External, format!("on another process: {message}")))
            }
        }
    }
}

impl Part {
    /// The dofs of `mesh` (this part's, at some geometry) as the stage numbers them.
    fn dofs(&self, mesh: &HighOrderMesh) -> DofMap {
        if self.stepping.condense {
            DofMap::condensed(mesh)
        } else {
            DofMap::new(mesh)
        }
    }

    /// The P1 level of this part: the rows of the prolongation for the
    /// owned system nodes (the P1 interpolant at each node: its barycentric
    /// coordinates in a cell holding it, on the cell's free vertices), and
    /// the owned free vertices' coordinates.
    fn coarse_level(&self, mesh: &HighOrderMesh, dofs: &DofMap) -> petsc::Coarse {
        let (dim, order) = (mesh.dim(), mesh.order);
        let nodes = NodeSet::new(mesh.simplex, order, mesh.spacing);
        let corner: Vec<usize> =
            (0..=dim).map(|k| (0..nodes.len()).find(|&a| nodes.multi[a][k] == order).expect("a corner")).collect();
        let bary: Vec<Vec<f64>> = (0..nodes.len()).map(|a| barycentric(&nodes.coords, &corner, a, dim)).collect();
        let mut done = vec![false; mesh.n_nodes()];
        let mut entries = Vec::new();
        for c in 0..mesh.n_cells() {
            let cell = mesh.cell(c);
            for (a, &n) in cell.iter().enumerate() {
                if done[n] || !self.owned[n] || dofs.system_row(n * dim).is_none() {
                    continue;
                }
                done[n] = true;
                for (k, &l) in bary[a].iter().enumerate() {
                    let v = cell[corner[k]];
                    if l.abs() > 1e-14 && self.petsc_vertex[v] != usize::MAX {
                        for d in 0..dim {
                            entries.push((self.petsc_node[n] * dim + d, self.petsc_vertex[v] * dim + d, l));
                        }
                    }
                }
            }
        }
        let mut owned: Vec<usize> =
            (0..mesh.n_nodes()).filter(|&n| self.owned[n] && self.petsc_vertex[n] != usize::MAX).collect();
        owned.sort_by_key(|&n| self.petsc_vertex[n]);
        let owned_coords = owned.iter().flat_map(|&n| mesh.coords[n * dim..(n + 1) * dim].iter().copied()).collect();
        petsc::Coarse {
            entries,
            n_owned: self.n_coarse_owned * dim,
            n_global: self.n_coarse_global * dim,
            owned_coords,
        }
    }
}

/// The barycentric coordinates of reference node `a` in the simplex of the
/// reference nodes `corner` (d + 1 of them), by Cramer's rule.
fn barycentric(coords: &[[f64; 3]], corner: &[usize], a: usize, dim: usize) -> Vec<f64> {
    let x0 = coords[corner[0]];
    let col = |k: usize| -> [f64; 3] { std::array::from_fn(|i| coords[corner[k]][i] - x0[i]) };
    let rhs: [f64; 3] = std::array::from_fn(|i| coords[a][i] - x0[i]);
    let det = |m: [[f64; 3]; 3]| -> f64 {
        if dim == 2 {
            m[0][0] * m[1][1] - m[0][1] * m[1][0]
        } else {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        }
    };
    // Rows are coordinates, columns the edge vectors X_k - X_0.
    let matrix = |replace: Option<usize>| -> [[f64; 3]; 3] {
        std::array::from_fn(|i| {
            std::array::from_fn(|j| match j {
                _ if j >= dim => 0.0,
                _ if Some(j) == replace => rhs[i],
                _ => col(j + 1)[i],
            })
        })
    };
    let full = det(matrix(None));
    let mut l: Vec<f64> = (0..dim).map(|j| det(matrix(Some(j))) / full).collect();
    l.insert(0, 1.0 - l.iter().sum::<f64>());
    l
}

/// A rank's owned nodes: global index, then position and rate per dof.
fn send_back(world: &World, part: &Part, mesh: &HighOrderMesh, first_rate: Option<&[f64]>) {
    let dim = mesh.dim();
    let dofs = part.dofs(mesh);
    let mut ints = Vec::new();
    let mut floats = Vec::new();
    for n in (0..mesh.n_nodes()).filter(|&n| part.owned[n]) {
        ints.push(part.global_node[n] as u64);
        floats.extend_from_slice(&mesh.coords[n * dim..(n + 1) * dim]);
        for c in 0..dim {
            let r = dofs.free_index(n * dim + c).and_then(|f| first_rate.map(|r| r[f]));
            floats.push(r.unwrap_or(f64::NAN));
        }
    }
    let root = world.0.process_at_rank(0);
    root.send(&ints[..]);
    root.send(&floats[..]);
}

/// A message pair from rank 0.
fn receive(world: &World) -> (Vec<u64>, Vec<f64>) {
    let root = world.0.process_at_rank(0);
    let (ints, _) = root.receive_vec::<u64>();
    let (floats, _) = root.receive_vec::<f64>();
    (ints, floats)
}

impl ElasticBackend for Lead {
    fn solve_increments(
        &self,
        mesh: &mut HighOrderMesh,
        material: LinearElastic,
        ubar: &[f64],
        stepping: &Stepping,
        rate: Option<&[f64]>,
        timings: &mut Timings,
        tick: &mut dyn FnMut(Stage, usize, usize) -> Result<()>,
    ) -> Result<IncrementsReport> {
        let world = &self.world;
        let size = self.size();
        let gdofs = if stepping.condense { DofMap::condensed(mesh) } else { DofMap::new(mesh) };
        // Rates per dof of the whole mesh (NaN where prescribed).
        let rate_per_dof: Option<Vec<f64>> = rate
            .filter(|r| r.len() == gdofs.n_free)
            .map(|r| (0..mesh.coords.len()).map(|d| gdofs.free_index(d).map_or(f64::NAN, |f| r[f])).collect());
        let parts = split(mesh, &gdofs, size)?;
        self.command(SOLVE, 0);
        let mut mine = None;
        for (r, layout) in parts.into_iter().enumerate() {
            let part = layout.into_part(mesh, material, stepping, ubar, rate_per_dof.as_deref());
            if r == 0 {
                mine = Some(part);
            } else {
                let (ints, floats) = part.encode();
                let to = world.0.process_at_rank(r as i32);
                to.send(&ints[..]);
                to.send(&floats[..]);
            }
        }
        let part = mine.expect("rank 0 has a part");
        // A cancelled run must not leave the other ranks in a collective
        // call: the progress callback's verdict is kept until the stage ends.
        let mut cancelled = None;
        let mut forward = |s: Stage, k: usize, n: usize| -> Result<()> {
            if cancelled.is_none() {
                cancelled = tick(s, k, n).err();
            }
            Ok(())
        };
        let (local_mesh, mut report) = part.solve(world, timings, &mut forward)?;
        report.first_rate = self.gather(mesh, &part, &local_mesh, report.first_rate.as_deref(), &gdofs);
        // The certified bounds were of rank 0's cells only.
        report.certified = None;
        report.n_free = gdofs.n_free;
        report.n_system = gdofs.n_system;
        match cancelled {
            Some(e) => Err(e),
            None => Ok(report),
        }
    }
}

impl Lead {
    /// Put into `mesh` the positions of every rank's owned nodes (rank 0's
    /// from `local_mesh`, the others' sent by [`send_back`]); return the
    /// first increment's rates on the whole mesh's free dofs (`dofs`), if
    /// the ranks had them (`first_rate`, rank 0's on its part's free dofs).
    fn gather(
        &self,
        mesh: &mut HighOrderMesh,
        part: &Part,
        local_mesh: &HighOrderMesh,
        first_rate: Option<&[f64]>,
        dofs: &DofMap,
    ) -> Option<Vec<f64>> {
        let dim = mesh.dim();
        let mut per_dof = vec![f64::NAN; mesh.coords.len()];
        let local_dofs = part.dofs(local_mesh);
        for n in (0..local_mesh.n_nodes()).filter(|&n| part.owned[n]) {
            let g = part.global_node[n];
            mesh.coords[g * dim..(g + 1) * dim].copy_from_slice(&local_mesh.coords[n * dim..(n + 1) * dim]);
            for c in 0..dim {
                if let (Some(f), Some(r)) = (local_dofs.free_index(n * dim + c), first_rate) {
                    per_dof[g * dim + c] = r[f];
                }
            }
        }
        for r in 1..self.size() {
            let from = self.world.0.process_at_rank(r as i32);
            let (ints, _) = from.receive_vec::<u64>();
            let (floats, _) = from.receive_vec::<f64>();
            for (k, &g) in ints.iter().enumerate() {
                let (g, row) = (g as usize, &floats[k * 2 * dim..(k + 1) * 2 * dim]);
                mesh.coords[g * dim..(g + 1) * dim].copy_from_slice(&row[..dim]);
                per_dof[g * dim..(g + 1) * dim].copy_from_slice(&row[dim..]);
            }
        }
        first_rate.map(|_| by_free_index(dofs, &per_dof))
    }
}

/// The values `per_dof` (one per dof) of the free dofs of `dofs`, in their order.
fn by_free_index(dofs: &DofMap, per_dof: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; dofs.n_free];
    for (d, &v) in per_dof.iter().enumerate() {
        if let Some(f) = dofs.free_index(d) {
            out[f] = v;
        }
    }
    out
}

/// Which cells and nodes each rank takes, and PETSc's numbering.
struct Layout {
    cells: Vec<usize>,
    /// Global nodes of the part: vertices first, each group ascending.
    nodes: Vec<usize>,
    owned: Vec<bool>,
    petsc_node: Vec<usize>,
    petsc_vertex: Vec<usize>,
    first_owned: usize,
    n_owned: usize,
    n_global: usize,
    n_coarse_owned: usize,
    n_coarse_global: usize,
}

/// Partition `mesh`'s cells over `size` ranks (METIS on the dual graph), own
/// each node by the lowest rank among its cells', and number the system
/// nodes for PETSc rank by rank.
fn split(mesh: &HighOrderMesh, dofs: &DofMap, size: usize) -> Result<Vec<Layout>> {
    let dim = mesh.dim();
    let part = crate::solver::partition(mesh, size)?;
    let mut owner = vec![usize::MAX; mesh.n_nodes()];
    for c in 0..mesh.n_cells() {
        for &n in mesh.cell(c) {
            owner[n] = owner[n].min(part[c]);
        }
    }
    let is_system = |n: usize| dofs.system_row(n * dim).is_some();
    // Row blocks rank by rank: the system nodes, and the free vertices (the P1 level).
    let number = |keep: &dyn Fn(usize) -> bool| {
        let mut index = vec![usize::MAX; mesh.n_nodes()];
        let mut first = vec![0usize; size + 1];
        let mut next = 0;
        for r in 0..size {
            first[r] = next;
            for n in (0..mesh.n_nodes()).filter(|&n| owner[n] == r && keep(n)) {
                index[n] = next;
                next += 1;
            }
        }
        first[size] = next;
        (index, first)
    };
    let (petsc_node, first) = number(&is_system);
    let (petsc_vertex, first_vertex) = number(&|n| n < mesh.n_vertices && is_system(n));
    let mut layouts = Vec::with_capacity(size);
    for r in 0..size {
        let cells: Vec<usize> = (0..mesh.n_cells()).filter(|&c| part[c] == r).collect();
        let mut used: Vec<usize> = cells.iter().flat_map(|&c| mesh.cell(c).iter().copied()).collect();
        used.sort_unstable();
        used.dedup();
        let (mut nodes, others): (Vec<usize>, Vec<usize>) = used.into_iter().partition(|&n| n < mesh.n_vertices);
        nodes.extend(others);
        layouts.push(Layout {
            owned: nodes.iter().map(|&n| owner[n] == r).collect(),
            petsc_node: nodes.iter().map(|&n| petsc_node[n]).collect(),
            petsc_vertex: nodes.iter().map(|&n| petsc_vertex[n]).collect(),
            cells,
            nodes,
            first_owned: first[r] * dim,
            n_owned: (first[r + 1] - first[r]) * dim,
            n_global: first[size] * dim,
            n_coarse_owned: first_vertex[r + 1] - first_vertex[r],
            n_coarse_global: first_vertex[size],
        });
    }
    Ok(layouts)
}

impl Layout {
    fn into_part(
        self,
        mesh: &HighOrderMesh,
        material: LinearElastic,
        stepping: &Stepping,
        ubar: &[f64],
        rate: Option<&[f64]>,
    ) -> Part {
        let dim = mesh.dim();
        let mut local = vec![usize::MAX; mesh.n_nodes()];
        for (l, &g) in self.nodes.iter().enumerate() {
            local[g] = l;
        }
        let per_node = |v: &[f64]| -> Vec<f64> {
            self.nodes.iter().flat_map(|&g| v[g * dim..(g + 1) * dim].iter().copied()).collect()
        };
        let sub = HighOrderMesh {
            simplex: mesh.simplex,
            order: mesh.order,
            spacing: mesh.spacing,
            coords: per_node(&mesh.coords),
            cells: self.cells.iter().flat_map(|&c| mesh.cell(c).iter().map(|&g| local[g])).collect(),
            n_vertices: self.nodes.iter().filter(|&&g| g < mesh.n_vertices).count(),
            constraint: self
                .nodes
                .iter()
                .map(|&g| {
                    if mesh.constraint[g] == NodeConstraint::Free {
                        NodeConstraint::Free
                    } else {
                        NodeConstraint::Fixed
                    }
                })
                .collect(),
        };
        Part {
            mesh: sub,
            material,
            stepping: Stepping { parallel: Parallel::Serial, ..stepping.clone() },
            ubar: per_node(ubar),
            rate: rate.map(per_node),
            global_node: self.nodes,
            owned: self.owned,
            petsc_node: self.petsc_node,
            petsc_vertex: self.petsc_vertex,
            n_coarse_owned: self.n_coarse_owned,
            n_coarse_global: self.n_coarse_global,
            global_cell: self.cells,
            first_owned: self.first_owned,
            n_owned: self.n_owned,
            n_global: self.n_global,
        }
    }
}

/// The agreement of a part's decisions over `MPI_COMM_WORLD`.
struct MpiCollective {
    world: SimpleCommunicator,
    global_cell: Vec<usize>,
}
// SAFETY: as `World`.
unsafe impl Send for MpiCollective {}
unsafe impl Sync for MpiCollective {}

impl MpiCollective {
    /// [`Collective::first`] over `world`: the smallest key with its rank
    /// (all-reduce), then that rank's message (broadcast).
    fn first_on(world: &SimpleCommunicator, local: Option<(u64, String)>) -> Option<(u64, String)> {
        let size = world.size() as usize;
        let key = local.as_ref().map_or(u64::MAX, |(k, _)| *k);
        let mut keys = vec![0u64; size];
        world.all_gather_into(&key, &mut keys[..]);
        let (winner, &best) = keys.iter().enumerate().min_by_key(|&(r, k)| (*k, r))?;
        if best == u64::MAX {
            return None;
        }
        let mut len = local.as_ref().map_or(0, |(_, m)| m.len() as u64);
        let root = world.process_at_rank(winner as i32);
        root.broadcast_into(&mut len);
        let mut bytes = if world.rank() as usize == winner {
            local.map(|(_, m)| m.into_bytes()).unwrap_or_default()
        } else {
            vec![0u8; len as usize]
        };
        // An empty buffer's address is 0x1, OpenMPI's MPI_IN_PLACE: never send one.
        if len > 0 {
            root.broadcast_into(&mut bytes[..]);
        }
        Some((best, String::from_utf8_lossy(&bytes).into_owned()))
    }
}

impl Collective for MpiCollective {
    fn first(&self, local: Option<(u64, String)>) -> Option<(u64, String)> {
        MpiCollective::first_on(&self.world, local)
    }
    fn global_cell(&self, local: usize) -> usize {
        self.global_cell[local]
    }
}

/// The linear solver of a part: its local system summed with the other
/// processes' in PETSc.
struct PetscSolver {
    world: SimpleCommunicator,
    global: Vec<usize>,
    first_owned: usize,
    n_owned: usize,
    n_global: usize,
    block: usize,
    owned_coords: Vec<f64>,
    /// The P1 level, until the system is built.
    coarse: Mutex<Option<petsc::Coarse>>,
    system: Mutex<Option<petsc::PetscSystem>>,
}
// SAFETY: as `World`.
unsafe impl Send for PetscSolver {}
unsafe impl Sync for PetscSolver {}

impl SystemSolver for PetscSolver {
    fn solve(&self, _: CsrView<'_>, _: &[f64], _: &mut [f64]) -> std::result::Result<(), String> {
        Err("the distributed solver takes the lower triangle".into())
    }

    fn takes_lower_triangle(&self) -> bool {
        true
    }

    fn solve_lower(
        &self,
        a: LowerCscView<'_>,
        rhs: &[f64],
        x: &mut [f64],
    ) -> std::result::Result<Option<usize>, String> {
        let mut guard = self.system.lock().unwrap_or_else(|e| e.into_inner());
        if guard.is_none() {
            let pattern = SymmetricCsc { n: a.n, col_ptr: a.col_ptr.to_vec(), row_idx: a.row_idx.to_vec() };
            *guard = Some(petsc::PetscSystem::new(
                self.world.as_raw(),
                &pattern,
                &self.global,
                self.first_owned,
                self.n_owned,
                self.n_global,
                self.block,
                self.owned_coords.clone(),
                self.coarse.lock().unwrap_or_else(|e| e.into_inner()).take(),
            )?);
        }
        let system = guard.as_mut().expect("just set");
        system.set_values(a.values);
        let solved = system.solve(rhs, x, RTOL)?;
        for (x, &g) in x.iter_mut().zip(&self.global) {
            *x = solved.all[g];
        }
        Ok(Some(solved.iterations))
    }

    fn name(&self) -> &'static str {
        "petsc-cg-pmg"
    }
}
