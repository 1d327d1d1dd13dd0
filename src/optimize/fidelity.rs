//! How far the curved boundary lies from the geometry between its nodes:
//! the guard that lets the polish slide boundary nodes without losing the
//! boundary's accuracy.
//!
//! A node placed by the boundary placement sits where the interpolant of its
//! facet is closest to the geometry; sliding it along its entity keeps the
//! node on the geometry but moves the interpolant off it between the nodes.
//! The guard samples each boundary piece of a cell (a facet on a curve or
//! surface, and in 3D an edge on a curve) at the points of the equispaced
//! lattice of order 2p on it but its nodes (which lie on the entity), and
//! projects them onto the piece's entity. A
//! slide is kept only if every piece it moves stays within the larger of
//! [`FIDELITY_FACTOR`] times its own distance before the polish and the
//! largest distance of the whole boundary before the polish: the
//! boundary's worst distance to the geometry at most doubles, and falls
//! with p at the placement's rate. (Allowing only the smaller of the two
//! cost up to 0.14 of min Q3 on three STEP parts.)
//!
//! Both figures are measured only when needed ([`Baseline`]): a piece's own
//! distance when a slide first moves it, unless the piece lies within the
//! whole boundary's lower bound (below), once that is known, which settles
//! it; when a slide moves a piece by more
//! than [`FIDELITY_FACTOR`] times its own, first a lower bound of the whole
//! boundary's (each piece at one sample point, its probe), which settles it
//! when the piece is within it; only otherwise are pieces sampled in full,
//! in decreasing order of their probe's distance, until one is as far as
//! the slid piece (the slide is kept) or none is left (it is not). The
//! answers are those of the whole boundary measured up front, which took
//! up to 0.31 s of 0.55 s of the optimisation on STEP parts (wrenchnut at
//! p = 2), where every slide beyond twice its own distance stayed within
//! 0.4 of the whole boundary's; sampling the whole boundary whenever a
//! slide went beyond the probes still took 160,000 of the 270,000
//! projected points of wrenchnut at p = 3, where the farthest probe's
//! piece alone settled every question.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::Mutex;

use super::gather;
use crate::geometry::Projector;
use crate::mesh::NodeConstraint;
use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing};

/// One kind of boundary piece of a cell: a facet (the face opposite a
/// vertex) or, in 3D, an edge.
#[derive(Debug, Clone)]
struct Piece {
    /// The cell's vertices on it (local indices).
    vertices: Vec<usize>,
    /// Its other nodes (local indices).
    inner: Vec<usize>,
    /// The entity dimension it lies on when on the boundary.
    edim: usize,
    /// The cell's basis at its sample points, `npc` values per point.
    values: Vec<f64>,
    /// The sample point farthest from the piece's nodes (reference
    /// coordinates): the one point at which [`Baseline::bound`] samples it.
    probe: usize,
}

/// The boundary pieces of the reference cell of one order, with their sample points.
#[derive(Debug, Clone)]
pub(super) struct Pieces {
    dim: usize,
    npc: usize,
    pieces: Vec<Piece>,
}

/// The boundary's distance from the geometry between its nodes: per piece
/// (by its sorted vertices) and the largest. The tests' yardstick: the
/// whole boundary measured at once.
#[cfg(test)]
#[derive(Debug, Clone)]
struct Distances {
    by_piece: BTreeMap<Vec<usize>, f64>,
    level: f64,
}

/// The boundary as it was before the polish, measured lazily: each piece's
/// distance from the geometry when first asked for; for the whole
/// boundary, the distance at each piece's probe once, then pieces in full
/// as [`Baseline::within`] needs them. Its answers are those of everything
/// measured up front, whatever the order of the questions: each figure is
/// a function of the positions before the polish alone.
#[derive(Debug)]
pub(super) struct Baseline {
    /// Every node's coordinates before the polish.
    coords: Vec<f64>,
    /// The pieces measured so far (None: the projector failed on it).
    by_piece: Mutex<BTreeMap<Vec<usize>, Option<f64>>>,
    /// The whole boundary, swept on first need (None: the projector failed).
    sweep: Mutex<Option<Option<Sweep>>>,
}

/// The whole boundary's pieces by decreasing distance at their probe, and
/// how far down that list they have been sampled in full.
#[derive(Debug)]
struct Sweep {
    /// The largest distance at a probe: a lower bound of the whole boundary's.
    bound: f64,
    /// (the piece's kind, the first node of its cell in the mesh's cell
    /// list, its entity), by decreasing probe distance.
    order: Vec<(usize, usize, (usize, i32))>,
    /// The pieces of `order` before this one are sampled in full (where
    /// the projector fails on a piece, `order` ends with it).
    next: usize,
    /// Their largest distance: at most the whole boundary's, and equal to
    /// it once `next` reaches the end (if the projector failed nowhere).
    largest: f64,
}

/// Pieces sampled in full together, at first: the batch doubles each time
/// (most questions are settled by the first piece).
const FIRST_BATCH: usize = 1;

impl Baseline {
    /// A baseline whose whole boundary's largest distance is `level`.
    #[cfg(test)]
    fn with_level(coords: &[f64], level: f64) -> Baseline {
        let b = Baseline::new(coords);
        let sweep = Sweep { bound: level, order: Vec::new(), next: 0, largest: level };
        *b.sweep.lock().expect("just made") = Some(Some(sweep));
        b
    }

    /// How many of the boundary's pieces are sampled in full, of how many;
    /// None before the probes.
    #[cfg(test)]
    fn swept(&self) -> Option<(usize, usize)> {
        self.sweep.lock().unwrap().as_ref().map(|s| s.as_ref().map_or((0, 0), |s| (s.next, s.order.len())))
    }

    /// The whole boundary's lower bound ([`Sweep::bound`]) if it has been
    /// measured (and the projector did not fail on it).
    fn bound(&self) -> Option<f64> {
        self.sweep.lock().ok()?.as_ref()?.as_ref().map(|s| s.bound)
    }

    /// The baseline of a mesh whose nodes are at `coords`; nothing measured yet.
    pub(super) fn new(coords: &[f64]) -> Baseline {
        Baseline { coords: coords.to_vec(), by_piece: Mutex::new(BTreeMap::new()), sweep: Mutex::new(None) }
    }

    /// Whether `now` is at most the whole boundary's largest distance plus
    /// `slack`, the boundary being the pieces of the mesh `cells`; false if
    /// the projector fails on the probes, and where it fails on a piece,
    /// the largest of the pieces before it in the order. Measures the
    /// probes on first call, and then only the pieces needed (the probes'
    /// lower bound, then the pieces in full by decreasing probe distance
    /// until one is at least `now`).
    fn within(
        &self,
        pieces: &Pieces,
        projector: &Mutex<&dyn Projector>,
        cells: &[usize],
        constraint: &[NodeConstraint],
        now: f64,
        slack: f64,
    ) -> bool {
        // Held while measuring: the projector serialises the calls anyway,
        // and a second thread would measure the same pieces.
        let Ok(mut sweep) = self.sweep.lock() else { return false };
        let sweep = sweep.get_or_insert_with(|| self.probe_all(pieces, projector, cells, constraint));
        let Some(sweep) = sweep.as_mut() else { return false };
        if now <= sweep.bound + slack {
            return true;
        }
        let mut batch = FIRST_BATCH;
        while sweep.next < sweep.order.len() && now > sweep.largest + slack {
            let end = (sweep.next + batch).min(sweep.order.len());
            if let Some(d) = self.measure(pieces, projector, cells, &sweep.order[sweep.next..end]) {
                sweep.largest = sweep.largest.max(d);
                sweep.next = end;
            } else {
                // The projector failed in this batch: its pieces one by one,
                // up to the first that fails, where the sweep ends. So the
                // answers are those of the pieces before the first failing
                // one in the order, whatever the batches and the order of
                // the questions.
                while sweep.next < end {
                    let Some(d) = self.measure(pieces, projector, cells, &sweep.order[sweep.next..sweep.next + 1]) else {
                        break;
                    };
                    sweep.largest = sweep.largest.max(d);
                    sweep.next += 1;
                }
                sweep.order.truncate(sweep.next);
            }
            batch *= 2;
        }
        now <= sweep.largest + slack
    }

    /// The whole boundary's pieces by decreasing distance at their probe; None if the projector fails.
    fn probe_all(&self, pieces: &Pieces, projector: &Mutex<&dyn Projector>, cells: &[usize], constraint: &[NodeConstraint]) -> Option<Sweep> {
        let (dim, npc) = (pieces.dim, pieces.npc);
        let mut seen = BTreeSet::new();
        let mut found = Vec::new();
        let mut points: BTreeMap<(usize, i32), Vec<[f64; 3]>> = BTreeMap::new();
        for (c, cell) in cells.chunks_exact(npc).enumerate() {
            let xe = gather(&self.coords, cell, dim);
            for (kind, piece) in pieces.pieces.iter().enumerate() {
                let Some(entity) = entity(piece, cell, constraint) else { continue };
                if !seen.insert(key(piece, cell)) {
                    continue;
                }
                let at = points.entry(entity).or_default();
                found.push((kind, c * npc, entity, at.len()));
                at.push(pieces.point(piece, &xe, piece.probe));
            }
        }
        let mut distance = BTreeMap::new();
        for (entity, pts) in points {
            distance.insert(entity, distances(projector, entity, &pts)?);
        }
        let mut order: Vec<(f64, usize)> = found.iter().enumerate().map(|(i, f)| (distance[&f.2][f.3], i)).collect();
        order.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let bound = order.first().map_or(0.0, |o| o.0);
        let order = order.into_iter().map(|(_, i)| (found[i].0, found[i].1, found[i].2)).collect();
        Some(Sweep { bound, order, next: 0, largest: 0.0 })
    }

    /// The largest distance of `list`'s pieces sampled in full (each
    /// recorded as that piece's, and those already known not measured
    /// again); None if the projector fails. The points of each entity go
    /// to the projector in one call.
    fn measure(
        &self,
        pieces: &Pieces,
        projector: &Mutex<&dyn Projector>,
        cells: &[usize],
        list: &[(usize, usize, (usize, i32))],
    ) -> Option<f64> {
        let (dim, npc) = (pieces.dim, pieces.npc);
        // Per entity: its sample points, and each piece's key with the end of its points.
        type Batch = (Vec<[f64; 3]>, Vec<(Vec<usize>, usize)>);
        let mut points: BTreeMap<(usize, i32), Batch> = BTreeMap::new();
        let mut largest = 0.0f64;
        for &(kind, first, entity) in list {
            let (piece, cell) = (&pieces.pieces[kind], &cells[first..first + npc]);
            let k = key(piece, cell);
            if let Some(&known) = self.by_piece.lock().ok()?.get(&k) {
                largest = largest.max(known?);
                continue;
            }
            let (pts, ends) = points.entry(entity).or_default();
            pts.extend(pieces.points(piece, &gather(&self.coords, cell, dim)));
            ends.push((k, pts.len()));
        }
        for (entity, (pts, ends)) in points {
            let d = distances(projector, entity, &pts)?;
            let mut known = self.by_piece.lock().ok()?;
            let mut start = 0;
            for (k, end) in ends {
                let worst = d[start..end].iter().fold(0.0, |w: f64, &x| w.max(x));
                largest = largest.max(worst);
                known.entry(k).or_insert(Some(worst));
                start = end;
            }
        }
        Some(largest)
    }

    /// The distance of `piece` of the cell with nodes `cell` from `entity`,
    /// measured on first call.
    fn piece(&self, pieces: &Pieces, projector: &Mutex<&dyn Projector>, piece: &Piece, cell: &[usize], entity: (usize, i32)) -> Option<f64> {
        let k = key(piece, cell);
        if let Some(&d) = self.by_piece.lock().ok()?.get(&k) {
            return d;
        }
        // Measured outside the lock: another thread may measure the same
        // piece meanwhile, to the same value.
        let d = pieces.distance(projector, piece, entity, &gather(&self.coords, cell, pieces.dim));
        self.by_piece.lock().ok()?.insert(k, d);
        d
    }
}

/// A distance this small against the patch size counts as on the geometry
/// (a planar facet's round-off).
const ROUND_OFF: f64 = 1e-9;

/// How much farther than before the polish the boundary between the nodes
/// may lie from the geometry: a fixed factor keeps the order of convergence.
pub(super) const FIDELITY_FACTOR: f64 = 2.0;

impl Pieces {
    pub(super) fn new(basis: &LagrangeBasis) -> Pieces {
        let (simplex, p) = (basis.simplex(), basis.order());
        let (dim, nv) = (simplex.dim(), simplex.n_vertices());
        let nodes = basis.nodes();
        let lattice = NodeSet::new(simplex, 2 * p, NodeSpacing::Equispaced);
        let mut kinds: Vec<(Vec<usize>, usize)> = (0..nv).map(|o| ((0..nv).filter(|&v| v != o).collect(), dim - 1)).collect();
        if dim == 3 {
            for i in 0..nv {
                for j in i + 1..nv {
                    kinds.push((vec![i, j], 1));
                }
            }
        }
        let pieces = kinds
            .into_iter()
            .map(|(vertices, edim)| {
                let on = |m: &[usize; 4]| (0..nv).all(|v| vertices.contains(&v) || m[v] == 0);
                let inner = (0..nodes.len())
                    .filter(|&a| on(&nodes.multi[a]) && nodes.multi[a][..nv].iter().filter(|&&k| k > 0).count() > 1)
                    .collect();
                // Lattice points on the piece but its nodes: the nodes lie
                // on the entity (the vertices as given, the others placed
                // or slid onto it), so only the points between them can
                // stray. Whole lattices of nodes coincide with lattice
                // points when equispaced (every order 2 mesh: the edge
                // midpoints), single ones otherwise (the centroid at p = 3).
                let at_node = |x: &[f64; 3]| {
                    vertices.iter().chain(&inner).any(|&a| (0..dim).all(|d| (x[d] - nodes.coords[a][d]).abs() < 1e-12))
                };
                let points: Vec<[f64; 3]> = (0..lattice.len())
                    .filter(|&i| on(&lattice.multi[i]) && !lattice.multi[i][..nv].contains(&(2 * p)))
                    .map(|i| lattice.coords[i])
                    .filter(|x| !at_node(x))
                    .collect();
                let values = basis.tabulate(&points).values;
                let apart = |x: &[f64; 3]| {
                    let near = |a: usize| (0..dim).map(|d| (x[d] - nodes.coords[a][d]).powi(2)).sum::<f64>();
                    vertices.iter().chain(&inner).map(|&a| near(a)).fold(f64::INFINITY, f64::min)
                };
                let probe = (0..points.len()).max_by(|&i, &j| apart(&points[i]).total_cmp(&apart(&points[j])).then(j.cmp(&i)));
                Piece { vertices, inner, edim, values, probe: probe.unwrap_or(0) }
            })
            .collect();
        Pieces { dim, npc: nodes.len(), pieces }
    }

    /// The distance from the geometry of every boundary piece of the mesh
    /// with `cells` (`npc` nodes each) at `coords`, sampled between the
    /// nodes (with `probe`, at each piece's probe alone: a lower bound);
    /// None if the projector fails. The points of each entity go to the
    /// projector in one call.
    #[cfg(test)]
    fn distances(
        &self,
        projector: &Mutex<&dyn Projector>,
        cells: &[usize],
        constraint: &[NodeConstraint],
        coords: &[f64],
        probe: bool,
    ) -> Option<Distances> {
        let (dim, npc) = (self.dim, self.npc);
        let mut seen = BTreeSet::new();
        // Per entity: its sample points, and each piece's key with the end of its points.
        type Batch = (Vec<[f64; 3]>, Vec<(Vec<usize>, usize)>);
        let mut points: BTreeMap<(usize, i32), Batch> = BTreeMap::new();
        for cell in cells.chunks_exact(npc) {
            let xe = gather(coords, cell, dim);
            for piece in &self.pieces {
                let Some(entity) = entity(piece, cell, constraint) else { continue };
                let k = key(piece, cell);
                if !seen.insert(k.clone()) {
                    continue;
                }
                let (pts, ends) = points.entry(entity).or_default();
                match probe {
                    true => pts.push(self.point(piece, &xe, piece.probe)),
                    false => pts.extend(self.points(piece, &xe)),
                }
                ends.push((k, pts.len()));
            }
        }
        let mut out = Distances { by_piece: BTreeMap::new(), level: 0.0 };
        for (entity, (pts, ends)) in points {
            let d = distances(projector, entity, &pts)?;
            let mut start = 0;
            for (k, end) in ends {
                let worst = d[start..end].iter().fold(0.0, |w: f64, &x| w.max(x));
                out.level = out.level.max(worst);
                out.by_piece.insert(k, worst);
                start = end;
            }
        }
        Some(out)
    }

    /// Whether the polish's new positions keep the boundary of `cells`
    /// within [`FIDELITY_FACTOR`] times each piece's distance from the
    /// geometry `before` the polish, or within the largest of them over the
    /// whole mesh (`all_cells`), whichever is larger: every boundary piece
    /// holding a node of `moved` is sampled with the nodes at `after`
    /// (element coordinates of each cell, `npc × dim`). `size` is the
    /// patch's length scale. False also if the projector fails.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn faithful(
        &self,
        projector: &Mutex<&dyn Projector>,
        cells: &[&[usize]],
        all_cells: &[usize],
        constraint: &[NodeConstraint],
        moved: &BTreeSet<usize>,
        after: &[Vec<f64>],
        before: &Baseline,
        size: f64,
    ) -> bool {
        let mut seen = BTreeSet::new();
        for (k, cell) in cells.iter().enumerate() {
            for piece in &self.pieces {
                if !piece.inner.iter().any(|&a| moved.contains(&cell[a])) {
                    continue;
                }
                let Some(entity) = entity(piece, cell, constraint) else { continue };
                if !seen.insert(key(piece, cell)) {
                    continue;
                }
                let Some(now) = self.distance(projector, piece, entity, &after[k]) else {
                    return false;
                };
                let slack = ROUND_OFF * size;
                // Within the whole boundary's lower bound, once that is
                // measured, the piece passes whatever its own distance
                // before: on the screw at p = 2, 851 of the 879 pieces
                // checked, whose distances before took 6,174 projected
                // points of 28,431.
                if before.bound().is_some_and(|bound| now <= bound + slack) {
                    continue;
                }
                let Some(was) = before.piece(self, projector, piece, cell, entity) else {
                    return false;
                };
                if now <= FIDELITY_FACTOR * was + slack {
                    continue;
                }
                if !before.within(self, projector, all_cells, constraint, now, slack) {
                    return false;
                }
            }
        }
        true
    }

    /// The largest distance from `entity` of `piece`'s sample points on the
    /// element with node coordinates `xe`; None if the projector fails.
    fn distance(&self, projector: &Mutex<&dyn Projector>, piece: &Piece, entity: (usize, i32), xe: &[f64]) -> Option<f64> {
        farthest(projector, entity, &self.points(piece, xe))
    }

    /// The sample points of `piece` on the element with node coordinates `xe`.
    fn points(&self, piece: &Piece, xe: &[f64]) -> Vec<[f64; 3]> {
        (0..piece.values.len() / self.npc).map(|i| self.point(piece, xe, i)).collect()
    }

    /// The `i`-th sample point of `piece` on the element with node coordinates `xe`.
    fn point(&self, piece: &Piece, xe: &[f64], i: usize) -> [f64; 3] {
        let (dim, npc) = (self.dim, self.npc);
        let mut x = [0.0; 3];
        for (a, &w) in piece.values[i * npc..(i + 1) * npc].iter().enumerate() {
            for d in 0..dim {
                x[d] += w * xe[a * dim + d];
            }
        }
        x
    }
}

/// The largest distance of `points` from `entity`; None if the projector fails.
fn farthest(projector: &Mutex<&dyn Projector>, entity: (usize, i32), points: &[[f64; 3]]) -> Option<f64> {
    Some(distances(projector, entity, points)?.into_iter().fold(0.0, f64::max))
}

/// The distance of each of `points` from `entity`; None if the projector
/// fails or a distance is not finite.
fn distances(projector: &Mutex<&dyn Projector>, entity: (usize, i32), points: &[[f64; 3]]) -> Option<Vec<f64>> {
    let mut out = vec![[f64::NAN; 3]; points.len()];
    projector.lock().ok()?.project(entity.0, entity.1, points, &mut out).ok()?;
    points
        .iter()
        .zip(&out)
        .map(|(x, y)| Some((0..3).map(|i| (x[i] - y[i]).powi(2)).sum::<f64>().sqrt()).filter(|d| d.is_finite()))
        .collect()
}

/// The piece's vertices in the mesh, sorted: the same piece of two cells has the same key.
fn key(piece: &Piece, cell: &[usize]) -> Vec<usize> {
    let mut key: Vec<usize> = piece.vertices.iter().map(|&a| cell[a]).collect();
    key.sort_unstable();
    key
}

/// The entity `piece` of the cell with nodes `cell` lies on: that of its
/// inner nodes when they all lie on one entity of the piece's dimension;
/// None for a piece inside the domain or across entities.
fn entity(piece: &Piece, cell: &[usize], constraint: &[NodeConstraint]) -> Option<(usize, i32)> {
    let mut on = None;
    for &a in &piece.inner {
        match constraint[cell[a]] {
            NodeConstraint::OnEntity { dim, tag } if dim == piece.edim => match on {
                None => on = Some((dim, tag)),
                Some(e) if e != (dim, tag) => return None,
                _ => {}
            },
            // Lower-dimensional entities (curves on a facet's edge) are
            // sampled as their own pieces.
            NodeConstraint::OnEntity { dim, .. } if dim < piece.edim => {}
            _ => return None,
        }
    }
    on
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::Simplex;

    /// The projector onto the unit circle (entity (1, 1)) or sphere ((2, 1)).
    struct Round;
    impl Projector for Round {
        fn project(&self, _: usize, _: i32, points: &[[f64; 3]], out: &mut [[f64; 3]]) -> Result<(), String> {
            for (x, y) in points.iter().zip(out.iter_mut()) {
                let r = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
                *y = [x[0] / r, x[1] / r, x[2] / r];
            }
            Ok(())
        }
    }

    /// A triangle of order p with its edge opposite vertex 0 on the unit
    /// circle between angles 0 and θ: its nodes placed at the angles of the
    /// node set (`slide` adds to the first inner node's angle).
    fn arc_triangle(p: usize, theta: f64, slide: f64) -> (Vec<f64>, Vec<NodeConstraint>, LagrangeBasis) {
        let basis = LagrangeBasis::new(&NodeSet::new(Simplex::Tri, p, NodeSpacing::Optimal));
        let nodes = basis.nodes();
        let (v1, v2) = ([1.0, 0.0], [theta.cos(), theta.sin()]);
        let v0 = [0.0, 0.0];
        let mut xe = Vec::new();
        let mut constraint = Vec::new();
        let mut first = true;
        for a in 0..nodes.len() {
            let l = nodes.barycentric(a);
            if l[0].abs() < 1e-12 && nodes.multi[a][1] > 0 && nodes.multi[a][2] > 0 {
                let mut angle = theta * l[2];
                if first {
                    angle += slide;
                    first = false;
                }
                xe.extend([angle.cos(), angle.sin()]);
                constraint.push(NodeConstraint::OnEntity { dim: 1, tag: 1 });
            } else {
                xe.extend((0..2).map(|d| l[0] * v0[d] + l[1] * v1[d] + l[2] * v2[d]));
                constraint.push(if l[0].abs() < 1e-12 { NodeConstraint::Fixed } else { NodeConstraint::Free });
            }
        }
        (xe, constraint, basis)
    }

    #[test]
    fn the_distance_between_the_nodes_falls_with_the_order_and_grows_when_a_node_slides() {
        let projector: &dyn Projector = &Round;
        let projector = Mutex::new(projector);
        let theta = 0.5;
        let mut last = f64::INFINITY;
        for p in 2..=5 {
            let (xe, constraint, basis) = arc_triangle(p, theta, 0.0);
            let pieces = Pieces::new(&basis);
            let edge = &pieces.pieces[0];
            assert_eq!(edge.inner.len(), p - 1);
            let cell: Vec<usize> = (0..xe.len() / 2).collect();
            assert_eq!(entity(edge, &cell, &constraint), Some((1, 1)));
            // The other edges are inside the domain.
            assert_eq!(entity(&pieces.pieces[1], &cell, &constraint), None);
            let d = pieces.distance(&projector, edge, (1, 1), &xe).unwrap();
            assert!(d > 0.0 && d < 0.5 * last, "p = {p}: {d:e} after {last:e}");
            last = d;
            // A node slid by a tenth of the arc moves the interpolant off the circle.
            let (slid, _, _) = arc_triangle(p, theta, 0.1 * theta / p as f64);
            let now = pieces.distance(&projector, edge, (1, 1), &slid).unwrap();
            assert!(now > FIDELITY_FACTOR * d, "p = {p}: slid {now:e}, placed {d:e}");
            let moved: BTreeSet<usize> = edge.inner.iter().copied().collect();
            let cells = [cell.as_slice()];
            let before = pieces.distances(&projector, &cell, &constraint, &xe, false).unwrap();
            assert!((before.level - d).abs() <= 1e-15, "p = {p}: largest {:e}, the edge's {d:e}", before.level);
            assert_eq!(before.by_piece.get(&key(edge, &cell)), Some(&d));
            // The same, with the whole boundary's largest distance set to `level`.
            let faithful = |after: &[f64], level: f64| {
                let before = Baseline::with_level(&xe, level);
                pieces.faithful(&projector, &cells, &cell, &constraint, &moved, &[after.to_vec()], &before, 1.0)
            };
            assert!(faithful(&xe, 0.0));
            assert!(!faithful(&slid, 0.0));
            // Allowed as far as the boundary's largest distance before, no farther,
            assert!(faithful(&slid, now));
            assert!(!faithful(&slid, 0.9 * now));
            // or as far as twice its own.
            // (Sliding one way can bring it nearer: the nodes are not where
            // the largest distance is smallest.)
            let nudges = [3.0, 1.0, 0.3, -3.0, -1.0, -0.3].map(|f| arc_triangle(p, theta, f * d).0);
            let within = nudges.iter().find(|x| {
                let near = pieces.distance(&projector, edge, (1, 1), x).unwrap();
                near > 1.05 * d && near < FIDELITY_FACTOR * d
            });
            let nudged = within.unwrap_or_else(|| panic!("p = {p}: no nudge moves the edge by less than twice {d:e}"));
            assert!(faithful(nudged, 0.0));
        }
    }

    /// [`Round`], counting the points it projects.
    struct Counting(std::sync::atomic::AtomicUsize);
    impl Projector for Counting {
        fn project(&self, dim: usize, tag: i32, points: &[[f64; 3]], out: &mut [[f64; 3]]) -> Result<(), String> {
            self.0.fetch_add(points.len(), std::sync::atomic::Ordering::Relaxed);
            Round.project(dim, tag, points, out)
        }
    }

    #[test]
    fn the_baseline_samples_the_whole_boundary_only_for_a_slide_beyond_twice_its_own_distance() {
        // Two triangles of order 3 on the unit circle, side by side (the
        // second turned by θ): a slide of the first's edge asks for that
        // edge's distance alone; a larger one for the whole boundary's, which
        // is the edge's too here, so the answers are those of a baseline
        // measured up front.
        let (p, theta) = (3, 0.5);
        let (xe, constraint, basis) = arc_triangle(p, theta, 0.0);
        let pieces = Pieces::new(&basis);
        let npc = xe.len() / 2;
        let turn = |x: &[f64]| -> Vec<f64> {
            let (c, s) = (theta.cos(), theta.sin());
            x.chunks_exact(2).flat_map(|v| [c * v[0] - s * v[1], s * v[0] + c * v[1]]).collect()
        };
        let coords: Vec<f64> = xe.iter().copied().chain(turn(&xe)).collect();
        let constraint: Vec<NodeConstraint> = constraint.iter().chain(&constraint).copied().collect();
        let cells: Vec<usize> = (0..2 * npc).collect();
        let edge = &pieces.pieces[0];
        let d = pieces.distance(&Mutex::new(&Round as &dyn Projector), edge, (1, 1), &xe).unwrap();
        let moved: BTreeSet<usize> = edge.inner.iter().copied().collect();
        let first = [&cells[..npc]];
        let nudges = [3.0, 1.0, 0.3, -3.0, -1.0, -0.3].map(|f| arc_triangle(p, theta, f * d).0);
        let measure = |x: &[f64]| pieces.distance(&Mutex::new(&Round as &dyn Projector), edge, (1, 1), x).unwrap();
        let near = nudges.iter().find(|x| (1.05 * d..FIDELITY_FACTOR * d).contains(&measure(x))).unwrap();
        let (far, _, _) = arc_triangle(p, theta, 0.1 * theta / p as f64);
        let counting = Counting(Default::default());
        let projector = Mutex::new(&counting as &dyn Projector);
        let points = || counting.0.load(std::sync::atomic::Ordering::Relaxed);
        let eager = Baseline::with_level(&coords, d);
        let lazy = Baseline::new(&coords);
        let check = |before: &Baseline, after: &[f64]| {
            pieces.faithful(&projector, &first, &cells, &constraint, &moved, &[after.to_vec()], before, 1.0)
        };
        // Within twice the edge's own distance: its samples before and after, nothing else.
        let start = points();
        assert!(check(&lazy, near));
        let per_sample = 2 * edge.values.len() / npc;
        assert_eq!(points() - start, per_sample, "the edge sampled before and after");
        assert_eq!(lazy.swept(), None, "the whole boundary not sampled");
        assert!(check(&eager, near));
        // Beyond: the whole boundary, once; both edges on the circle are as far.
        assert_eq!(check(&lazy, &far), check(&eager, &far));
        assert!(!check(&lazy, &far));
        assert_eq!(lazy.swept(), Some((2, 2)), "both edges sampled in full");
        let start = points();
        check(&lazy, &far);
        assert_eq!(points() - start, per_sample / 2, "measured once: only the slid edge again");
    }

    #[test]
    fn a_slide_within_the_boundarys_probes_needs_no_other_sample_of_the_boundary() {
        // Two triangles of order 3 on the unit circle: the first's arc θ, the
        // second's 3θ, much farther from the circle between its nodes. A
        // slide of the first beyond twice its own distance but within the
        // second's is settled by the probes (one point per edge), and gives
        // the answer of the whole boundary measured up front.
        let (p, theta) = (3, 0.3);
        let (xe, constraint, basis) = arc_triangle(p, theta, 0.0);
        let (wide, _, _) = arc_triangle(p, 3.0 * theta, 0.0);
        let pieces = Pieces::new(&basis);
        let npc = xe.len() / 2;
        let coords: Vec<f64> = xe.iter().chain(&wide).copied().collect();
        let constraint: Vec<NodeConstraint> = constraint.iter().chain(&constraint).copied().collect();
        let cells: Vec<usize> = (0..2 * npc).collect();
        let edge = &pieces.pieces[0];
        let round = Mutex::new(&Round as &dyn Projector);
        let d = pieces.distance(&round, edge, (1, 1), &xe).unwrap();
        let (slid, _, _) = arc_triangle(p, theta, 0.03 * theta / p as f64);
        let now = pieces.distance(&round, edge, (1, 1), &slid).unwrap();
        let whole = pieces.distances(&round, &cells, &constraint, &coords, false).unwrap().level;
        let probes = pieces.distances(&round, &cells, &constraint, &coords, true).unwrap().level;
        assert!(now > FIDELITY_FACTOR * d && now < probes && probes <= whole, "{d:e} {now:e} {probes:e} {whole:e}");
        let counting = Counting(Default::default());
        let projector = Mutex::new(&counting as &dyn Projector);
        let moved: BTreeSet<usize> = edge.inner.iter().copied().collect();
        let lazy = Baseline::new(&coords);
        assert!(pieces.faithful(&projector, &[&cells[..npc]], &cells, &constraint, &moved, std::slice::from_ref(&slid), &lazy, 1.0));
        assert_eq!(lazy.swept(), Some((0, 2)), "probed, not sampled in full");
        // The edge before and after, and one probe per edge on the circle.
        let per_edge = edge.values.len() / npc;
        let points = || counting.0.load(std::sync::atomic::Ordering::Relaxed);
        assert_eq!(points(), 2 * per_edge + 2);
        // With the probes measured first, the same slide is settled by them
        // and the edge after it: its distance before is not needed.
        let probed = Baseline::new(&coords);
        assert!(probed.within(&pieces, &projector, &cells, &constraint, 0.0, 0.0));
        let start = points();
        assert!(pieces.faithful(&projector, &[&cells[..npc]], &cells, &constraint, &moved, &[slid], &probed, 1.0));
        assert_eq!(points() - start, per_edge, "the edge after the slide alone");
    }

    #[test]
    fn beyond_the_probes_the_pieces_are_sampled_farthest_probe_first_until_one_is_as_far() {
        // Three triangles of order 3 on the unit circle, arcs θ, 3θ and 2θ,
        // the second with a node moved off the circle so that its probe is
        // not its farthest point: the second's edge has the farthest probe.
        // A slide of the first beyond that probe but within the second
        // edge's full distance is settled by that edge alone; beyond it, by
        // every edge. Both answers are those of the whole boundary measured
        // up front.
        let (p, theta) = (3, 0.3);
        let (xe, constraint, basis) = arc_triangle(p, theta, 0.0);
        let pieces = Pieces::new(&basis);
        let npc = xe.len() / 2;
        let round = Mutex::new(&Round as &dyn Projector);
        let measure = |x: &[f64]| pieces.distance(&round, &pieces.pieces[0], (1, 1), x).unwrap();
        let mut off = arc_triangle(p, 3.0 * theta, 0.0).0;
        let bumped = constraint.iter().position(|c| matches!(c, NodeConstraint::OnEntity { .. })).unwrap();
        for v in &mut off[2 * bumped..2 * bumped + 2] {
            *v *= 1.002;
        }
        let arcs = [xe.clone(), off, arc_triangle(p, 2.0 * theta, 0.0).0];
        let coords: Vec<f64> = arcs.concat();
        let constraint: Vec<NodeConstraint> = (0..3).flat_map(|_| constraint.iter().copied()).collect();
        let cells: Vec<usize> = (0..3 * npc).collect();
        let edge = &pieces.pieces[0];
        let probes = pieces.distances(&round, &cells, &constraint, &coords, true).unwrap();
        let whole = pieces.distances(&round, &cells, &constraint, &coords, false).unwrap();
        let wide = measure(&arcs[1]);
        assert_eq!(whole.level, wide);
        assert!(probes.level < wide, "the probe {:e} is the edge's farthest point {wide:e}", probes.level);
        let slides: Vec<(f64, Vec<f64>)> =
            (1..2000).map(|k| arc_triangle(p, theta, k as f64 * 1e-4 * theta).0).map(|x| (measure(&x), x)).collect();
        let pick = |lo: f64, hi: f64| slides.iter().find(|(d, _)| *d > lo && *d <= hi).map(|s| s.1.clone());
        let inside = pick(probes.level, wide).unwrap_or_else(|| panic!("no slide between the probe {:e} and the edge {wide:e}", probes.level));
        let beyond = pick(wide * 1.01, f64::INFINITY).expect("a slide beyond every edge");
        let counting = Counting(Default::default());
        let projector = Mutex::new(&counting as &dyn Projector);
        let moved: BTreeSet<usize> = edge.inner.iter().copied().collect();
        let first = [&cells[..npc]];
        let check = |before: &Baseline, after: &[f64]| {
            pieces.faithful(&projector, &first, &cells, &constraint, &moved, &[after.to_vec()], before, 1.0)
        };
        let eager = Baseline::with_level(&coords, whole.level);
        let lazy = Baseline::new(&coords);
        let points = || counting.0.load(std::sync::atomic::Ordering::Relaxed);
        assert!(check(&eager, &inside));
        let start = points();
        assert!(check(&lazy, &inside));
        let per_edge = edge.values.len() / npc;
        // The slid edge before and after, one probe per edge, the wide edge in full.
        assert_eq!(points() - start, 3 * per_edge + 3);
        assert_eq!(lazy.swept(), Some((1, 3)));
        assert!(!check(&eager, &beyond));
        assert!(!check(&lazy, &beyond));
        assert_eq!(lazy.swept(), Some((3, 3)), "every edge sampled in full");
        // A projector that fails on the far end of the widest arc (not on
        // its probe): the sweep ends before that arc, first in the order,
        // and the answers do not depend on the order of the questions.
        struct Failing;
        impl Projector for Failing {
            fn project(&self, dim: usize, tag: i32, points: &[[f64; 3]], out: &mut [[f64; 3]]) -> Result<(), String> {
                match points.iter().any(|x| x[1].atan2(x[0]) > 2.5 * 0.3) {
                    true => Err("off the end".into()),
                    false => Round.project(dim, tag, points, out),
                }
            }
        }
        let failing = Mutex::new(&Failing as &dyn Projector);
        let ask = |before: &Baseline, after: &[f64]| {
            pieces.faithful(&failing, &first, &cells, &constraint, &moved, &[after.to_vec()], before, 1.0)
        };
        let (one, two) = (Baseline::new(&coords), Baseline::new(&coords));
        let first_order = (ask(&one, &inside), ask(&one, &beyond));
        let second_order = (ask(&two, &beyond), ask(&two, &inside));
        assert_eq!(first_order, (second_order.1, second_order.0));
        assert_eq!(first_order, (false, false), "the widest arc is not measured");
        assert_eq!((one.swept(), two.swept()), (Some((0, 0)), Some((0, 0))));
    }

    #[test]
    fn a_tetrahedron_has_four_facets_and_six_edges_sampled_between_their_nodes() {
        // (order, spacing, sample points per facet, per edge): the lattice of
        // order 2p on the piece but the points at its nodes. A triangle
        // holds (2p + 1)(2p + 2)/2 lattice points, an edge 2p + 1; all the
        // nodes are lattice points when equispaced (every node at p = 2),
        // the vertices and the face centroid only at p = 3 otherwise.
        for (p, spacing, facet, edge) in [
            (3, NodeSpacing::Optimal, 28 - 3 - 1, 7 - 2),
            (2, NodeSpacing::Optimal, 15 - 3 - 3, 5 - 2 - 1),
            (3, NodeSpacing::Equispaced, 28 - 10, 7 - 4),
        ] {
            let nodes = NodeSet::new(Simplex::Tet, p, spacing);
            let basis = LagrangeBasis::new(&nodes);
            let pieces = Pieces::new(&basis);
            assert_eq!(pieces.pieces.len(), 10);
            for (k, piece) in pieces.pieces.iter().enumerate() {
                // Facet: 3 (p - 1) edge nodes and (p - 1)(p - 2)/2 face nodes.
                let (edim, inner, count) =
                    if k < 4 { (2, 3 * (p - 1) + (p - 1) * (p - 2) / 2, facet) } else { (1, p - 1, edge) };
                assert_eq!((piece.edim, piece.inner.len(), piece.values.len() / pieces.npc), (edim, inner, count));
                // Each sample point is where no node is: no basis function is 1 there.
                for values in piece.values.chunks_exact(pieces.npc) {
                    assert!(values.iter().all(|v| (v - 1.0).abs() > 1e-9), "p = {p}: a sample point at a node");
                }
            }
        }
    }
}
