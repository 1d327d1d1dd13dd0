//! A mesh the host already holds spread over its MPI processes: each
//! process gives its own cells, with its vertices' global ids, its boundary
//! facets and feature edges, and its own projector
//! (`hoc_mesh_create_distributed` in the C ABI).
//!
//! A run is collective. Every process checks its share and the settings,
//! which must be the same everywhere, and all agree on the first error.
//! Process 0 then gathers the shares into the whole linear mesh and runs the
//! pipeline on it, as `hocurve-mpi` does: the elastic stages are split
//! again over every process ([`Lead`]), and each projection is made by the
//! lowest process that holds the entity, with its own projector. The other
//! processes serve both ([`serve`]). Process 0 then sends each process its
//! share of the curved mesh: its own cells (the cells the repair made go
//! with the input cell they came from), their nodes numbered locally, the
//! vertices first in the host's order, with each node's index in the whole
//! curved mesh and its owner, the lowest process holding it. The figures of
//! the run (quality, increments, solves, ...) are the whole mesh's on every
//! process. A failure anywhere ends the run on every process with the same
//! error, and leaves every process's session as it was.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use mpi::ffi;
use mpi::raw::FromRaw;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use super::{serve, Lead, MpiCollective};
use crate::curve::{CurveReport, ElasticStop, StepBack, StepBackReason, Timings};
use crate::geometry::Projector;
use crate::mesh::{HighOrderMesh, LinearMesh, NodeConstraint, RepairSummary};
use crate::optimize::OptimizeReport;
use crate::quality::{ElementQuality, MeshQuality};
use crate::session::{ProgressFn, Session};
use crate::solver::{FallbackReason, SolveLog, SolvedBy};
use crate::{Error, Result, SolverFailure};

/// The communicator behind the host's Fortran handle `comm`, duplicated so
/// that the run's messages never meet the host's. MPI must be initialised,
/// with at least `MPI_THREAD_SERIALIZED` (the run calls MPI from its worker
/// threads, one at a time).
pub fn communicator(comm: i32) -> Result<SimpleCommunicator> {
    if !mpi::environment::is_initialized() || mpi::environment::is_finalized() {
        return Err(Error::InvalidInput("MPI is not initialised (or already finalised)".into()));
    }
    if !matches!(mpi::environment::threading_support(), mpi::Threading::Serialized | mpi::Threading::Multiple) {
        return Err(Error::InvalidInput(
            "MPI was initialised without thread support: initialise it with \
             MPI_Init_thread(..., MPI_THREAD_SERIALIZED or MPI_THREAD_MULTIPLE, ...)"
                .into(),
        ));
    }
    // SAFETY: MPI is initialised; a bad handle is MPI's error, which aborts.
    unsafe {
        let host = ffi::RSMPI_Comm_f2c(comm);
        if host == ffi::RSMPI_COMM_NULL {
            return Err(Error::InvalidInput(format!("communicator {comm} is MPI_COMM_NULL")));
        }
        let mut dup = ffi::RSMPI_COMM_NULL;
        ffi::MPI_Comm_dup(host, &mut dup);
        Ok(SimpleCommunicator::from_raw(dup))
    }
}

/// The first error of any process (the lowest process's), on every process.
pub fn agree(comm: &SimpleCommunicator, local: Result<()>) -> Result<()> {
    let local = local.err().map(|e| (0, encode_error(&e)));
    match MpiCollective::first_on(comm, local) {
        None => Ok(()),
        Some((_, e)) => Err(decode_error(&e)),
    }
}

/// Of every process's `local` failure (a message), the lowest process's,
/// on every process of the host's communicator `comm`.
pub fn first_failure(comm: i32, local: Option<String>) -> Result<Option<String>> {
    let comm = communicator(comm)?;
    Ok(MpiCollective::first_on(&comm, local.map(|m| (0, m))).map(|(_, m)| m))
}

/// Curve the distributed mesh of which `session` is this process's share,
/// with every other process; see the module documentation.
pub fn run(session: &mut Session, increments: usize) -> Result<()> {
    let part = session.partition().ok_or_else(|| Error::InvalidInput("not a distributed mesh".into()))?;
    let comm = communicator(part.comm)?;
    // On the host's communicator, that PETSc's may outlive this run's.
    // SAFETY: MPI is initialised (`communicator` checked).
    let host = unsafe { ffi::RSMPI_Comm_f2c(part.comm) };
    super::petsc::initialize_on(Some(host)).map_err(|e| Error::solver(SolverFailure::Setup, e))?;
    agree(&comm, check(session, increments))?;
    // Every process's settings must be process 0's.
    let mine = settings(session, increments);
    let mut wire = Wire::default();
    if comm.rank() == 0 {
        wire.text(&mine);
    }
    broadcast(&comm, &mut wire);
    let first = Reader::new(wire.ints, wire.floats).text();
    let same = if first == mine {
        Ok(())
    } else {
        Err(Error::InvalidInput(format!(
            "the settings differ between processes: process 0 has {first}, process {} has {mine}",
            comm.rank()
        )))
    };
    agree(&comm, same)?;
    let share = Share::of(session);
    if comm.rank() == 0 {
        lead(session, comm, share, increments)
    } else {
        follow(session, comm, share)
    }
}

/// What a process checks of its own share before a run.
fn check(session: &Session, increments: usize) -> Result<()> {
    if increments == 0 {
        return Err(Error::InvalidInput("increments must be >= 1".into()));
    }
    let linear = session.input();
    if (!linear.facets.is_empty() || !linear.feature_edges.is_empty()) && !session.has_projector() {
        return Err(Error::InvalidInput("boundary facets are tagged but no projector is set".into()));
    }
    if session.has_external_solver() {
        return Err(Error::InvalidInput(
            "a distributed mesh is solved by PETSc: the host's linear solver cannot be used".into(),
        ));
    }
    Ok(())
}

/// The settings that must agree, in words.
fn settings(session: &Session, increments: usize) -> String {
    let o = session.options();
    format!(
        "order {}, {:?} nodes, {}, {:?} E = {} nu = {}, {increments} increments, adaptive {:?} ({} splits), \
         Newton {} x {}, caps removed {} (retry {}), repair {}, condensation {}, {:?}, straight {:?}, dimension {}",
        o.order,
        o.spacing,
        o.formulation.name(),
        o.material,
        o.young,
        o.poisson,
        o.adaptive,
        o.max_splits,
        o.tolerance,
        o.max_iterations,
        o.remove_caps,
        o.retry_keep_caps,
        o.repair,
        o.condense,
        o.optimize,
        session.straight_tags(),
        session.dim(),
    )
}

/// One process's linear share, in global vertex ids, as sent to process 0.
struct Share {
    global_vertex: Vec<u64>,
    coords: Vec<f64>,
    cells: Vec<u64>,
    facets: Vec<u64>,
    facet_tags: Vec<i32>,
    edges: Vec<u64>,
    edge_tags: Vec<i32>,
}

impl Share {
    fn of(session: &Session) -> Share {
        let m = session.input();
        let ids = &session.partition().expect("a share").global_vertex;
        let global = |v: &[usize]| v.iter().map(|&i| ids[i]).collect();
        Share {
            global_vertex: ids.clone(),
            coords: m.coords.clone(),
            cells: global(&m.cells),
            facets: global(&m.facets),
            facet_tags: m.facet_tags.clone(),
            edges: global(&m.feature_edges),
            edge_tags: m.feature_edge_tags.clone(),
        }
    }

    fn encode(&self) -> (Vec<u64>, Vec<f64>) {
        let mut w = Wire::default();
        for v in [&self.global_vertex, &self.cells, &self.facets, &self.edges] {
            w.list(v);
        }
        for t in [&self.facet_tags, &self.edge_tags] {
            w.list(&t.iter().map(|&t| t as i64 as u64).collect::<Vec<_>>());
        }
        w.floats = self.coords.clone();
        (w.ints, w.floats)
    }

    fn decode(ints: Vec<u64>, floats: Vec<f64>) -> Share {
        let mut r = Reader::new(ints, Vec::new());
        let [global_vertex, cells, facets, edges] = std::array::from_fn(|_| r.list());
        let mut tags = || r.list().into_iter().map(|t| t as i64 as i32).collect();
        let (facet_tags, edge_tags) = (tags(), tags());
        Share { global_vertex, coords: floats, cells, facets, facet_tags, edges, edge_tags }
    }
}

/// The whole linear mesh from the processes' shares (in process order):
/// vertices numbered by ascending global id, cells process by process, and
/// each facet and feature edge once. Also which process each cell came
/// from with its index there, and the lowest process holding each entity.
struct Whole {
    mesh: LinearMesh,
    /// Per whole cell: (process, its index among that process's cells).
    origin: Vec<(usize, usize)>,
    /// Per process: the whole index of each of its vertices.
    vertex: Vec<Vec<usize>>,
    /// (entity dimension, tag) → the lowest process whose share has it.
    holder: HashMap<(usize, i32), usize>,
}

fn gather_whole(dim: usize, shares: &[Share]) -> Result<Whole> {
    let mut ids: Vec<u64> = shares.iter().flat_map(|s| s.global_vertex.iter().copied()).collect();
    ids.sort_unstable();
    ids.dedup();
    let index: HashMap<u64, usize> = ids.iter().enumerate().map(|(k, &g)| (g, k)).collect();
    let mut coords = vec![f64::NAN; ids.len() * dim];
    let mut from = vec![usize::MAX; ids.len()];
    let mut vertex = Vec::with_capacity(shares.len());
    for (r, s) in shares.iter().enumerate() {
        vertex.push(s.global_vertex.iter().map(|g| index[g]).collect::<Vec<_>>());
        for (k, g) in s.global_vertex.iter().enumerate() {
            let (v, x) = (index[g], &s.coords[k * dim..(k + 1) * dim]);
            if from[v] == usize::MAX {
                from[v] = r;
                coords[v * dim..(v + 1) * dim].copy_from_slice(x);
            } else {
                let y = &coords[v * dim..(v + 1) * dim];
                let scale = y.iter().chain(x).fold(1.0f64, |m, c| m.max(c.abs()));
                if x.iter().zip(y).any(|(a, b)| (a - b).abs() > 1e-12 * scale) {
                    return Err(Error::InvalidInput(format!(
                        "vertex {g} has other coordinates on process {r} than on process {}",
                        from[v]
                    )));
                }
            }
        }
    }
    let mut mesh = LinearMesh { dim, coords, ..Default::default() };
    let mut origin = Vec::new();
    let mut holder = HashMap::new();
    // Each facet or edge once, however many processes give it.
    let mut seen: HashMap<Vec<usize>, i32> = HashMap::new();
    for (r, s) in shares.iter().enumerate() {
        let n_cells = s.cells.len() / (dim + 1);
        mesh.cells.extend(s.cells.iter().map(|g| index[g]));
        origin.extend((0..n_cells).map(|c| (r, c)));
        for (entities, tags, d, edges) in
            [(&s.facets, &s.facet_tags, dim - 1, false), (&s.edges, &s.edge_tags, 1, true)]
        {
            let per = if edges { 2 } else { dim };
            for (e, &tag) in entities.chunks_exact(per).zip(tags) {
                let vs: Vec<usize> = e.iter().map(|g| index[g]).collect();
                let mut key = vs.clone();
                key.sort_unstable();
                key.push(edges as usize);
                holder.entry((d, tag)).or_insert(r);
                match seen.insert(key, tag) {
                    Some(t) if t != tag => {
                        return Err(Error::InvalidInput(format!(
                            "a {} is tagged {t} on one process and {tag} on process {r}",
                            if edges { "feature edge" } else { "boundary facet" }
                        )))
                    }
                    Some(_) => {}
                    None if edges => {
                        mesh.feature_edges.extend(vs);
                        mesh.feature_edge_tags.push(tag);
                    }
                    None => {
                        mesh.facets.extend(vs);
                        mesh.facet_tags.push(tag);
                    }
                }
            }
        }
    }
    Ok(Whole { mesh, origin, vertex, holder })
}

/// Process 0's projector for the whole mesh: each entity's points go to the
/// lowest process holding it, its own projector for its own entities.
struct Routed {
    /// Process 0's own projector, lent by its session for the run.
    own: Arc<Mutex<Option<Box<dyn Projector + Send>>>>,
    holder: HashMap<(usize, i32), usize>,
    lead: Arc<Lead>,
}

impl Projector for Routed {
    fn project(
        &self,
        d: usize,
        tag: i32,
        points: &[[f64; 3]],
        out: &mut [[f64; 3]],
    ) -> std::result::Result<(), String> {
        // Held for remote calls too: MPI is called by one thread at a time.
        let own = self.own.lock().unwrap_or_else(|e| e.into_inner());
        match (self.holder.get(&(d, tag)), own.as_ref()) {
            (Some(0) | None, Some(p)) => p.project(d, tag, points, out),
            (Some(0) | None, None) => Err(format!("no process has a projector for entity ({d}, {tag})")),
            (Some(&r), _) => self.lead.project_on(r, d, tag, points, out),
        }
    }
}

fn lead(session: &mut Session, comm: SimpleCommunicator, own: Share, increments: usize) -> Result<()> {
    let size = comm.size() as usize;
    let mut shares = vec![own];
    for r in 1..size {
        let (ints, floats) = receive(&comm, r);
        shares.push(Share::decode(ints, floats));
    }
    let lead = Arc::new(Lead::new(comm.duplicate()));
    let callbacks = session.take_callbacks();
    let whole = gather_whole(session.dim(), &shares);
    let (whole, callbacks, outcome) = match whole {
        Err(e) => (None, callbacks, Err(e)),
        Ok(whole) => {
            let (projector, progress) = callbacks;
            let own = Arc::new(Mutex::new(projector));
            let routed = Routed { own: own.clone(), holder: whole.holder.clone(), lead: lead.clone() };
            let (outcome, progress) = curve_whole(session, &whole.mesh, routed, progress, &lead, increments);
            let projector = own.lock().unwrap_or_else(|e| e.into_inner()).take();
            (Some(whole), (projector, progress), outcome)
        }
    };
    lead.stop();
    session.restore_callbacks(callbacks);
    let outcome = outcome.map(|s| (s, whole.expect("the run had a whole mesh")));
    agree(&comm, outcome.as_ref().map(|_| ()).map_err(Error::clone))?;
    let (curved, whole) = outcome.expect("agreed");
    let report = curved.report().expect("a curved session has a report");
    let mut wire = Wire::default();
    encode_report(&mut wire, report);
    broadcast(&comm, &mut wire);
    let curved_shares = split_curved(&curved, &whole, size);
    let mut mine = None;
    for (r, s) in curved_shares.into_iter().enumerate() {
        if r == 0 {
            mine = Some(s);
        } else {
            let (ints, floats) = s.encode();
            send(&comm, r, &ints, &floats);
        }
    }
    mine.expect("process 0 has a share").adopt_into(session, report.clone());
    Ok(())
}

/// Curve the whole mesh on process 0, lending it this session's settings
/// and callbacks; give the callbacks back.
fn curve_whole(
    session: &Session,
    mesh: &LinearMesh,
    routed: Routed,
    progress: Option<ProgressFn>,
    lead: &Arc<Lead>,
    increments: usize,
) -> (Result<Session>, Option<ProgressFn>) {
    let mut whole = match Session::try_new(mesh.clone()) {
        Ok(s) => s,
        Err(e) => return (Err(e), progress),
    };
    for d in [1, 2] {
        let tags: Vec<i32> = session.straight_tags().iter().filter(|(e, _)| *e == d).map(|&(_, t)| t).collect();
        if !tags.is_empty() {
            if let Err(e) = whole.set_straight_tags(d, &tags) {
                return (Err(e), progress);
            }
        }
    }
    if let Err(e) = whole.set_threads(session.threads()) {
        return (Err(e), progress);
    }
    whole.restore_callbacks((Some(Box::new(routed)), progress));
    let mut opts = session.options().clone();
    opts.parallel = lead.parallel();
    let outcome = whole.run_with(opts, increments);
    let (_, progress) = whole.take_callbacks();
    (outcome.map(|()| whole), progress)
}

fn follow(session: &mut Session, comm: SimpleCommunicator, share: Share) -> Result<()> {
    let (ints, floats) = share.encode();
    send(&comm, 0, &ints, &floats);
    let world = super::World(comm.duplicate());
    session.install(move |projector| {
        let world = world;
        serve(world.0, projector.map(|p| p as &dyn Projector))
    })??;
    agree(&comm, Ok(()))?;
    let mut wire = Wire::default();
    broadcast(&comm, &mut wire);
    let report = decode_report(&mut Reader::new(wire.ints, wire.floats), session);
    let (ints, floats) = receive(&comm, 0);
    CurvedShare::decode(ints, floats, session)?.adopt_into(session, report);
    Ok(())
}

/// One process's share of the curved mesh, numbered locally.
struct CurvedShare {
    mesh: HighOrderMesh,
    quality: Vec<ElementQuality>,
    /// Per cell, its input cell among the process's own.
    input_cell: Vec<usize>,
    global_node: Vec<u64>,
    owner: Vec<i32>,
}

/// Cut the curved whole mesh into the processes' shares.
fn split_curved(curved: &Session, whole: &Whole, size: usize) -> Vec<CurvedShare> {
    let m = curved.mesh();
    let input = curved.input_cells();
    let rank_of = |c: usize| whole.origin[input[c]].0;
    let mut owner = vec![i32::MAX; m.n_nodes()];
    for c in 0..m.n_cells() {
        for &n in m.cell(c) {
            owner[n] = owner[n].min(rank_of(c) as i32);
        }
    }
    let dim = m.dim();
    (0..size)
        .map(|r| {
            let cells: Vec<usize> = (0..m.n_cells()).filter(|&c| rank_of(c) == r).collect();
            // The process's vertices in its order, then the others its cells use.
            let mut nodes: Vec<usize> = whole.vertex[r].clone();
            let mut local = HashMap::with_capacity(nodes.len() * 4);
            for (l, &n) in nodes.iter().enumerate() {
                local.insert(n, l);
            }
            let mut extra: Vec<usize> = Vec::new();
            for &c in &cells {
                for &n in m.cell(c) {
                    if !local.contains_key(&n) && !extra.contains(&n) && n < m.n_vertices {
                        extra.push(n);
                    }
                }
            }
            extra.sort_unstable();
            let n_vertices = nodes.len() + extra.len();
            for &n in &extra {
                local.insert(n, nodes.len());
                nodes.push(n);
            }
            for &c in &cells {
                for &n in m.cell(c) {
                    if let std::collections::hash_map::Entry::Vacant(v) = local.entry(n) {
                        v.insert(nodes.len());
                        nodes.push(n);
                    }
                }
            }
            let mesh = HighOrderMesh {
                simplex: m.simplex,
                order: m.order,
                spacing: m.spacing,
                coords: nodes.iter().flat_map(|&n| m.coords[n * dim..(n + 1) * dim].iter().copied()).collect(),
                cells: cells.iter().flat_map(|&c| m.cell(c).iter().map(|n| local[n])).collect(),
                n_vertices,
                constraint: nodes.iter().map(|&n| m.constraint[n]).collect(),
            };
            CurvedShare {
                mesh,
                quality: cells.iter().map(|&c| curved.cell_quality()[c]).collect(),
                input_cell: cells.iter().map(|&c| whole.origin[input[c]].1).collect(),
                global_node: nodes.iter().map(|&n| n as u64).collect(),
                owner: nodes.iter().map(|&n| owner[n]).collect(),
            }
        })
        .collect()
}

impl CurvedShare {
    fn encode(&self) -> (Vec<u64>, Vec<f64>) {
        let m = &self.mesh;
        let mut w = Wire::default();
        w.int(m.n_vertices);
        w.list(&m.cells.iter().map(|&n| n as u64).collect::<Vec<_>>());
        w.list(&self.input_cell.iter().map(|&c| c as u64).collect::<Vec<_>>());
        w.list(&self.global_node);
        w.list(&self.owner.iter().map(|&o| o as u64).collect::<Vec<_>>());
        w.list(&m.constraint.iter().flat_map(|&c| constraint_code(c)).collect::<Vec<_>>());
        w.floats.extend_from_slice(&m.coords);
        for q in &self.quality {
            w.floats.extend_from_slice(&[q.q1, q.q2, q.q3, q.q4, q.q5]);
        }
        (w.ints, w.floats)
    }

    fn decode(ints: Vec<u64>, floats: Vec<f64>, session: &Session) -> Result<CurvedShare> {
        let straight = session.mesh();
        let dim = straight.dim();
        let mut r = Reader::new(ints, Vec::new());
        let n_vertices = r.int();
        let cells: Vec<usize> = r.list().into_iter().map(|n| n as usize).collect();
        let input_cell: Vec<usize> = r.list().into_iter().map(|c| c as usize).collect();
        let global_node = r.list();
        let owner = r.list().into_iter().map(|o| o as i32).collect();
        let constraint = r.list().chunks_exact(3).map(constraint_of).collect::<Vec<_>>();
        let n_nodes = global_node.len();
        let coords = floats[..n_nodes * dim].to_vec();
        let quality = floats[n_nodes * dim..]
            .chunks_exact(5)
            .map(|q| ElementQuality { q1: q[0], q2: q[1], q3: q[2], q4: q[3], q5: q[4] })
            .collect();
        let mesh = HighOrderMesh {
            simplex: straight.simplex,
            order: straight.order,
            spacing: straight.spacing,
            coords,
            cells,
            n_vertices,
            constraint,
        };
        Ok(CurvedShare { mesh, quality, input_cell, global_node, owner })
    }

    fn adopt_into(self, session: &mut Session, report: CurveReport) {
        let report = CurveReport { input_cell: self.input_cell, ..report };
        session.adopt(self.mesh, self.quality, report, (self.global_node, self.owner));
    }
}

/// A node's constraint as three integers: the kind, and an entity's dimension and tag.
fn constraint_code(c: NodeConstraint) -> [u64; 3] {
    match c {
        NodeConstraint::Free => [0, 0, 0],
        NodeConstraint::Fixed => [1, 0, 0],
        NodeConstraint::OnEntity { dim, tag } => [2, dim as u64, tag as i64 as u64],
    }
}

fn constraint_of(code: &[u64]) -> NodeConstraint {
    match *code {
        [2, dim, tag] => NodeConstraint::OnEntity { dim: dim as usize, tag: tag as i64 as i32 },
        [0, _, _] => NodeConstraint::Free,
        _ => NodeConstraint::Fixed,
    }
}

/// Process 0's `wire` on every process (the others pass an empty one).
fn broadcast(comm: &SimpleCommunicator, wire: &mut Wire) {
    let root = comm.process_at_rank(0);
    let mut len = [wire.ints.len() as u64, wire.floats.len() as u64];
    root.broadcast_into(&mut len[..]);
    wire.ints.resize(len[0] as usize, 0);
    wire.floats.resize(len[1] as usize, 0.0);
    root.broadcast_into(&mut wire.ints[..]);
    root.broadcast_into(&mut wire.floats[..]);
}

/// A message of integers and floats to process `rank`, and from it.
fn send(comm: &SimpleCommunicator, rank: usize, ints: &[u64], floats: &[f64]) {
    let to = comm.process_at_rank(rank as i32);
    to.send(ints);
    to.send(floats);
}

fn receive(comm: &SimpleCommunicator, rank: usize) -> (Vec<u64>, Vec<f64>) {
    let from = comm.process_at_rank(rank as i32);
    let (ints, _) = from.receive_vec::<u64>();
    let (floats, _) = from.receive_vec::<f64>();
    (ints, floats)
}

/// Integers and floats of a message, written in order.
#[derive(Default)]
struct Wire {
    ints: Vec<u64>,
    floats: Vec<f64>,
}

impl Wire {
    fn int(&mut self, v: usize) {
        self.ints.push(v as u64);
    }
    fn list(&mut self, v: &[u64]) {
        self.ints.push(v.len() as u64);
        self.ints.extend_from_slice(v);
    }
    fn text(&mut self, s: &str) {
        self.list(&s.bytes().map(u64::from).collect::<Vec<_>>());
    }
}

/// Reads what [`Wire`] wrote, in the same order.
struct Reader {
    ints: std::vec::IntoIter<u64>,
    floats: std::vec::IntoIter<f64>,
}

impl Reader {
    fn new(ints: Vec<u64>, floats: Vec<f64>) -> Reader {
        Reader { ints: ints.into_iter(), floats: floats.into_iter() }
    }
    fn int(&mut self) -> usize {
        self.ints.next().unwrap_or(0) as usize
    }
    fn float(&mut self) -> f64 {
        self.floats.next().unwrap_or(f64::NAN)
    }
    fn list(&mut self) -> Vec<u64> {
        let n = self.int();
        self.ints.by_ref().take(n).collect()
    }
    fn text(&mut self) -> String {
        String::from_utf8_lossy(&self.list().into_iter().map(|b| b as u8).collect::<Vec<_>>()).into_owned()
    }
}

/// An error as text, with its kind: what [`decode_error`] reads back.
fn encode_error(e: &Error) -> String {
    let (kind, message) = match e {
        Error::InvalidInput(m) => (0, m.as_str()),
        Error::Projection(m) => (1, m.as_str()),
        Error::Solver { kind, message } => {
            (10 + SOLVER_FAILURES.iter().position(|k| k == kind).unwrap_or(0), message.as_str())
        }
        Error::InvalidElement { message, .. } => (2, message.as_str()),
        Error::Io(m) => (3, m.as_str()),
        Error::Cancelled => (4, ""),
    };
    format!("{kind} {message}")
}

fn decode_error(s: &str) -> Error {
    let (kind, message) = s.split_once(' ').unwrap_or((s, ""));
    let message = message.to_string();
    match kind.parse::<usize>().unwrap_or(0) {
        0 => Error::InvalidInput(message),
        1 => Error::Projection(message),
        // The cell's index is the whole mesh's, not this process's.
        2 => Error::invalid_element(None, message),
        3 => Error::Io(message),
        4 => Error::Cancelled,
        k => Error::solver(SOLVER_FAILURES.get(k - 10).copied().unwrap_or(SolverFailure::External), message),
    }
}

const SOLVER_FAILURES: [SolverFailure; 7] = [
    SolverFailure::NotPositiveDefinite,
    SolverFailure::Singular,
    SolverFailure::NotConverged,
    SolverFailure::NonFinite,
    SolverFailure::Setup,
    SolverFailure::OutOfMemory,
    SolverFailure::External,
];
const STEP_BACK_REASONS: [StepBackReason; 4] = [
    StepBackReason::SampledInvalid,
    StepBackReason::CertifiedInvalid,
    StepBackReason::NewtonFailed,
    StepBackReason::Restarted,
];
const SOLVED_BY: [SolvedBy; 5] =
    [SolvedBy::Pcg, SolvedBy::PcgRestarted, SolvedBy::Direct, SolvedBy::DirectLu, SolvedBy::External];
const FALLBACKS: [FallbackReason; 6] = [
    FallbackReason::PreconditionerNotPositive,
    FallbackReason::Stagnation,
    FallbackReason::EigenvalueUnderestimated,
    FallbackReason::NotConverged,
    FallbackReason::NonFinite,
    FallbackReason::MatrixNotPositive,
];
/// The names a solve log can carry (a `&'static str`).
const SOLVER_NAMES: [&str; 1] = ["petsc-cg-pmg"];

fn code<T: PartialEq>(all: &[T], v: &T) -> usize {
    all.iter().position(|k| k == v).expect("every variant is listed")
}

/// The figures of a whole run that every process reports.
fn encode_report(w: &mut Wire, r: &CurveReport) {
    w.int(r.increments);
    w.int(r.adaptive as usize);
    w.list(&r.load_fractions.iter().map(|f| f.to_bits()).collect::<Vec<_>>());
    w.int(r.step_backs.len());
    for b in &r.step_backs {
        w.int(code(&STEP_BACK_REASONS, &b.reason));
        w.int(b.cell.map_or(0, |c| c + 1));
        w.floats.extend_from_slice(&[b.load, b.step]);
    }
    for n in [
        r.nodes,
        r.dofs,
        r.system_dofs,
        r.cells,
        r.reoriented_cells,
        r.removed_caps,
        r.projected_nodes,
        r.edges_along_curves,
    ] {
        w.int(n);
    }
    w.floats.push(r.max_projection_distance);
    w.text(r.caps_kept_after.as_deref().unwrap_or(""));
    w.text(r.caps_kept_failed.as_deref().unwrap_or(""));
    let p = &r.repair;
    for n in [
        p.bad_cells,
        p.surface_cells,
        p.bulge_cells,
        p.flips_23,
        p.flips_32,
        p.edge_removals,
        p.flips_22,
        p.surface_caps,
        p.cells_removed,
        p.cells_added,
        p.bad_cells_left,
        p.edge_splits,
        p.surface_flips,
    ] {
        w.int(n);
    }
    encode_quality(w, &r.quality);
    let s = &r.solves;
    w.text(s.solver);
    w.list(&s.iterations.iter().map(|&n| n as u64).collect::<Vec<_>>());
    w.list(&s.solved_by.iter().map(|b| code(&SOLVED_BY, b) as u64).collect::<Vec<_>>());
    w.list(&s.fallback.iter().map(|f| f.map_or(0, |f| 1 + code(&FALLBACKS, &f) as u64)).collect::<Vec<_>>());
    w.int(s.by_products);
    w.int(s.assembled_after_products);
    w.int(r.elastic_stop.is_some() as usize);
    if let Some(e) = &r.elastic_stop {
        w.int(code(&STEP_BACK_REASONS, &e.reason));
        w.int(e.cell.map_or(0, |c| c + 1));
        w.int(e.restarted as usize);
        w.text(&e.detail);
        w.floats.push(e.load);
    }
    encode_optimization(w, &r.optimization);
}

fn decode_report(r: &mut Reader, session: &Session) -> CurveReport {
    let opts = session.options();
    let (increments, adaptive) = (r.int(), r.int() == 1);
    let load_fractions = r.list().into_iter().map(f64::from_bits).collect();
    let step_backs = (0..r.int())
        .map(|_| {
            let reason = STEP_BACK_REASONS[r.int().min(3)];
            let cell = r.int().checked_sub(1);
            StepBack { load: r.float(), step: r.float(), reason, cell }
        })
        .collect();
    let [nodes, dofs, system_dofs, cells, reoriented_cells, removed_caps, projected_nodes, edges_along_curves] =
        std::array::from_fn(|_| r.int());
    let max_projection_distance = r.float();
    let caps_kept_after = Some(r.text()).filter(|s| !s.is_empty());
    let caps_kept_failed = Some(r.text()).filter(|s| !s.is_empty());
    let [bad_cells, surface_cells, bulge_cells, flips_23, flips_32, edge_removals, flips_22, surface_caps, cells_removed, cells_added, bad_cells_left, edge_splits, surface_flips] =
        std::array::from_fn(|_| r.int());
    let repair = RepairSummary {
        bad_cells,
        surface_cells,
        bulge_cells,
        flips_23,
        flips_32,
        edge_removals,
        flips_22,
        surface_caps,
        cells_removed,
        cells_added,
        bad_cells_left,
        edge_splits,
        surface_flips,
    };
    let quality = decode_quality(r);
    let solves = decode_solves(r);
    let elastic_stop = (r.int() == 1).then(|| {
        let reason = STEP_BACK_REASONS[r.int().min(3)];
        let cell = r.int().checked_sub(1);
        let restarted = r.int() == 1;
        let detail = r.text();
        ElasticStop { load: r.float(), reason, cell, detail, restarted }
    });
    CurveReport {
        order: opts.order,
        formulation: opts.formulation,
        material: opts.material,
        young: opts.young,
        poisson: opts.poisson,
        increments,
        adaptive,
        max_splits: opts.max_splits,
        load_fractions,
        step_backs,
        nodes,
        dofs,
        system_dofs,
        cells,
        reoriented_cells,
        removed_caps,
        caps_kept_after,
        caps_kept_failed,
        repair,
        input_cell: Vec::new(),
        projected_nodes,
        max_projection_distance,
        edges_along_curves,
        quality,
        timings: Timings::default(),
        newton_history: Vec::new(),
        solves,
        elastic_stop,
        optimization: decode_optimization(r),
    }
}

fn encode_quality(w: &mut Wire, q: &MeshQuality) {
    w.floats.extend_from_slice(&[q.min_q1, q.min_q2, q.min_q3, q.min_q4, q.min_q5, q.mean_q3, q.certified_min_q3]);
    for n in [q.n_invalid, q.worst_cell, q.n_certified_invalid, q.n_uncertain] {
        w.int(n);
    }
    w.list(&q.histogram.iter().map(|&n| n as u64).collect::<Vec<_>>());
}

/// The linear solves of a report, as `encode_report` writes them.
fn decode_solves(r: &mut Reader) -> SolveLog {
    let name = r.text();
    SolveLog {
        solver: SOLVER_NAMES.iter().find(|&&n| n == name).copied().unwrap_or("external"),
        iterations: r.list().into_iter().map(|n| n as usize).collect(),
        solved_by: r.list().into_iter().map(|b| SOLVED_BY[(b as usize).min(4)]).collect(),
        fallback: r.list().into_iter().map(|f| (f as usize).checked_sub(1).map(|k| FALLBACKS[k.min(5)])).collect(),
        by_products: r.int(),
        assembled_after_products: r.int(),
    }
}

fn decode_quality(r: &mut Reader) -> MeshQuality {
    let [min_q1, min_q2, min_q3, min_q4, min_q5, mean_q3, certified_min_q3] = std::array::from_fn(|_| r.float());
    let [n_invalid, worst_cell, n_certified_invalid, n_uncertain] = std::array::from_fn(|_| r.int());
    let bins = r.list();
    MeshQuality {
        min_q1,
        min_q2,
        min_q3,
        min_q4,
        min_q5,
        mean_q3,
        n_invalid,
        worst_cell,
        histogram: std::array::from_fn(|k| bins.get(k).copied().unwrap_or(0) as usize),
        certified_min_q3,
        n_certified_invalid,
        n_uncertain,
    }
}

fn encode_optimization(w: &mut Wire, o: &OptimizeReport) {
    for n in [
        o.ran as usize,
        o.target_cells,
        o.cells_touched,
        o.nodes_moved,
        o.patches,
        o.rounds,
        o.cells_split,
        o.invalid_before,
        o.invalid_after,
    ] {
        w.int(n);
    }
    w.floats.extend_from_slice(&[o.min_q3_before, o.min_q3_after, o.seconds]);
}

fn decode_optimization(r: &mut Reader) -> OptimizeReport {
    let [ran, target_cells, cells_touched, nodes_moved, patches, rounds, cells_split, invalid_before, invalid_after] =
        std::array::from_fn(|_| r.int());
    OptimizeReport {
        ran: ran == 1,
        target_cells,
        cells_touched,
        nodes_moved,
        patches,
        rounds,
        cells_split,
        invalid_before,
        invalid_after,
        min_q3_before: r.float(),
        min_q3_after: r.float(),
        seconds: r.float(),
    }
}
