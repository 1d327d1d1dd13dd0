//! Element and mesh quality (paper section 5, eq. (27)).
//!
//! For an element e with straight-sided (affine) configuration X and curved
//! configuration x, F = ∂x/∂X = (∂x/∂ξ)(∂X/∂ξ)⁻¹ at each quadrature point of
//! a rule exact to degree 2p. X is the element of the straight (linear input)
//! mesh, as the curving sees it: the curving may move vertices (interior
//! ones by the elastic solve, or the one a removed boundary cap added), and
//! F then includes that motion. Without a straight mesh (a curved mesh read
//! from a file), X is the straight element through the curved vertices. With I1 = F:F, I2 = H:H (H = cof F), J = det F:
//!
//! Q_j = sqrt(min I_j / max I_j), j = 1, 2, and Q3 = min J / max J (the
//! scaled Jacobian). If J ≤ 0 somewhere the element is invalid and
//! Q3 = min J / max |J| ≤ 0. In 2D the 2×2 F is used, so Q1 = Q2.
//!
//! These are *sampled* measures. The sample set is the points of the
//! quadrature rule (interior) together with the equispaced lattice of order 2p
//! (vertices, edges and faces included, where the extremes of J usually sit);
//! an element could in principle still be inverted between samples.
//! [`certified`] closes that gap: bounds on det J over the whole element.
//! Read-only; never modifies the mesh.

pub mod certified;

pub use certified::{CertifiedJacobian, JacobianBernstein, Verdict};

use rayon::prelude::*;

use crate::linalg;
use crate::mapping::{self, ElementCache};
use crate::quadrature::{collapsed_rule, simplex_rule};
use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing};

/// Tabulation of `basis` at the quality sample points: the quadrature rule
/// exact to degree 2p and the equispaced lattice of order 2p.
pub fn sampling_cache(basis: &LagrangeBasis) -> ElementCache {
    let p = basis.order();
    let mut points = collapsed_rule(basis.simplex(), 2 * p).points;
    points.extend(NodeSet::new(basis.simplex(), 2 * p, NodeSpacing::Equispaced).coords);
    ElementCache::at_points(basis, &points)
}

/// Q1..Q5 of one element (Q4, Q5 are NaN without a fibre direction).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElementQuality {
    pub q1: f64,
    pub q2: f64,
    pub q3: f64,
    /// sqrt(min I4 / max I4), I4 = FN·FN (transversely isotropic models).
    pub q4: f64,
    /// sqrt(min I5 / max I5), I5 = FᵀFN·FᵀFN.
    pub q5: f64,
}

impl ElementQuality {
    /// The quality of an affine (straight-sided) element.
    pub const PERFECT: ElementQuality = ElementQuality { q1: 1.0, q2: 1.0, q3: 1.0, q4: f64::NAN, q5: f64::NAN };
}

impl ElementQuality {
    pub fn is_valid(&self) -> bool {
        self.q3 > 0.0
    }
}

/// Number of bins of the Q3 histogram over [0, 1].
pub const HISTOGRAM_BINS: usize = 10;

/// Mesh-wide reductions.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshQuality {
    pub min_q1: f64,
    pub min_q2: f64,
    pub min_q3: f64,
    /// NaN unless fibres were given (transversely isotropic models).
    pub min_q4: f64,
    pub min_q5: f64,
    pub mean_q3: f64,
    /// Number of elements with J ≤ 0 at a sample point.
    pub n_invalid: usize,
    /// Index of the element with the lowest Q3.
    pub worst_cell: usize,
    /// Counts of valid elements with Q3 in [k/10, (k+1)/10) (last bin includes 1).
    pub histogram: [usize; HISTOGRAM_BINS],
    /// A lower bound of min Q3 over the whole of every element (not only the
    /// samples), from the Bernstein bounds of det J ([`certified`]); NaN when
    /// not computed.
    pub certified_min_q3: f64,
    /// Elements with det J ≤ 0 at some point, found by the certified check.
    pub n_certified_invalid: usize,
    /// Elements whose sign the certified check could not decide.
    pub n_uncertain: usize,
}

/// Quality of one element with node coordinates `xe` (`dim` components per
/// node, native ordering, the first dim+1 nodes being the vertices) against
/// the straight element whose vertices are the first dim+1 nodes of `xs`
/// (the straight mesh's element; `xe` itself to measure against the straight
/// element through the curved vertices), with Q4 and Q5 when a unit `fibre`
/// N is given.
pub fn element_quality(cache: &ElementCache, xe: &[f64], xs: &[f64], fibre: Option<&[f64; 3]>) -> ElementQuality {
    JACOBIANS.with_borrow_mut(|jq| {
        linalg::with_avx2(
            #[inline(always)]
            || match cache.dim {
                2 => element_quality_in::<2>(cache, xe, xs, fibre, jq),
                _ => element_quality_in::<3>(cache, xe, xs, fibre, jq),
            },
        )
    })
}

thread_local! {
    /// ∂x/∂ξ at every sample point of one element ([`mapping::PointGradients::jacobians_into`]).
    static JACOBIANS: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// [`element_quality`] in dimension `D`: ∂x/∂ξ at every sample point first
/// (sums over the nodes in SIMD lanes over the points), then the invariants:
/// without a fibre, [`INVARIANT_LANES`] points at a time
/// ([`invariants_in_lanes`]), else point by point.
#[inline(always)]
fn element_quality_in<const D: usize>(
    cache: &ElementCache,
    xe: &[f64],
    xs: &[f64],
    fibre: Option<&[f64; 3]>,
    jq: &mut Vec<f64>,
) -> ElementQuality {
    let (jx_inv, _) = mapping::straight_inverse(D, xs);
    let nq = cache.n_points();
    cache.by_point.jacobians_into::<D>(xe, jq);
    let mut ext = Extremes::new();
    if fibre.is_none() {
        const L: usize = INVARIANT_LANES;
        let full = nq - nq % L;
        let mut lanes = [Extremes::new(); L];
        for q0 in (0..full).step_by(L) {
            let [i1, i2, j] = invariants_in_lanes::<D, L>(jq, nq, q0, &jx_inv);
            for (l, ext) in lanes.iter_mut().enumerate() {
                ext.add(i1[l], i2[l], j[l], None);
            }
        }
        for q in full..nq {
            let [[i1], [i2], [j]] = invariants_in_lanes::<D, 1>(jq, nq, q, &jx_inv);
            ext.add(i1, i2, j, None);
        }
        lanes.iter().for_each(|l| ext.merge(l));
        return ext.quality(false);
    }
    for q in 0..nq {
        let dxdxi = mapping::jacobian_at::<D>(jq, nq, q);
        let f = linalg::matmul(D, &dxdxi, &jx_inv);
        let (i1, i2) = strain_invariants(D, &f);
        // Q3 from det ∂x/∂ξ itself: the scaled Jacobian is a ratio, so the
        // affine factor of X cancels, and it must not set the sign: when X is
        // taken through the curved vertices, an interior vertex moved by the
        // curving (one that a removed boundary cap added) can leave that
        // straight tet inverted under an element that is valid everywhere.
        let j = linalg::det(D, &dxdxi);
        ext.add(i1, i2, j, fibre.map(|n| fibre_invariants(D, &f, n)));
    }
    ext.quality(fibre.is_some())
}

/// Sample points whose invariants [`element_quality`] computes side by side.
const INVARIANT_LANES: usize = 4;

/// I1 = F:F, I2 = H:H and J = det ∂x/∂ξ at the `L` sample points from `q0`
/// (F = ∂x/∂ξ X⁻¹, H = cof F; ∂x/∂ξ laid out as
/// [`mapping::PointGradients::jacobians_into`] writes it for `nq` points),
/// lane by lane with the operations of [`linalg::matmul`],
/// [`strain_invariants`] and [`linalg::det`] in their order: bitwise their
/// values. On the torus cavity at p = 4 the point-by-point invariants took
/// about half of the quality measures' time.
#[inline(always)]
fn invariants_in_lanes<const D: usize, const L: usize>(
    jq: &[f64],
    nq: usize,
    q0: usize,
    jx_inv: &linalg::Mat3,
) -> [[f64; L]; 3] {
    let mut m = [[[0.0; L]; 3]; 3];
    for i in 0..D {
        for j in 0..D {
            m[i][j].copy_from_slice(&jq[(i * D + j) * nq + q0..][..L]);
        }
    }
    let mut f = [[[0.0; L]; 3]; 3];
    for i in 0..D {
        for j in 0..D {
            for l in 0..L {
                // As `(0..D).map(..).sum()`: the first product, then the others in order.
                let mut s = m[i][0][l] * jx_inv[0][j];
                for k in 1..D {
                    s += m[i][k][l] * jx_inv[k][j];
                }
                f[i][j][l] = s;
            }
        }
    }
    let mut h = [[[0.0; L]; 3]; 3];
    for l in 0..L {
        if D == 2 {
            h[0][0][l] = f[1][1][l];
            h[0][1][l] = -f[1][0][l];
            h[1][0][l] = -f[0][1][l];
            h[1][1][l] = f[0][0][l];
        } else {
            for i in 0..3 {
                for j in 0..3 {
                    let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
                    let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
                    h[i][j][l] = f[i1][j1][l] * f[i2][j2][l] - f[i1][j2][l] * f[i2][j1][l];
                }
            }
        }
    }
    let (mut i1, mut i2, mut det) = ([0.0; L], [0.0; L], [0.0; L]);
    for l in 0..L {
        for i in 0..D {
            for j in 0..D {
                i1[l] += f[i][j][l] * f[i][j][l];
                i2[l] += h[i][j][l] * h[i][j][l];
            }
        }
        let m = |i: usize, j: usize| m[i][j][l];
        det[l] = if D == 2 {
            m(0, 0) * m(1, 1) - m(0, 1) * m(1, 0)
        } else {
            m(0, 0) * (m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1)) - m(0, 1) * (m(1, 0) * m(2, 2) - m(1, 2) * m(2, 0))
                + m(0, 2) * (m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0))
        };
    }
    [i1, i2, det]
}

/// Least and greatest values of the invariants over the sample points of
/// one element.
#[derive(Clone, Copy)]
struct Extremes {
    i1min: f64,
    i1max: f64,
    i2min: f64,
    i2max: f64,
    jmin: f64,
    jmax: f64,
    jabsmax: f64,
    i4min: f64,
    i4max: f64,
    i5min: f64,
    i5max: f64,
}

impl Extremes {
    /// Before any sample point.
    fn new() -> Extremes {
        let (i1min, i1max) = (f64::INFINITY, 0.0f64);
        let (i2min, i2max) = (f64::INFINITY, 0.0f64);
        let (jmin, jmax, jabsmax) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
        let (i4min, i4max, i5min, i5max) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
        Extremes { i1min, i1max, i2min, i2max, jmin, jmax, jabsmax, i4min, i4max, i5min, i5max }
    }

    /// Take in the extremes of other sample points.
    fn merge(&mut self, o: &Extremes) {
        self.i1min = self.i1min.min(o.i1min);
        self.i1max = self.i1max.max(o.i1max);
        self.i2min = self.i2min.min(o.i2min);
        self.i2max = self.i2max.max(o.i2max);
        self.jmin = self.jmin.min(o.jmin);
        self.jmax = self.jmax.max(o.jmax);
        self.jabsmax = self.jabsmax.max(o.jabsmax);
        self.i4min = self.i4min.min(o.i4min);
        self.i4max = self.i4max.max(o.i4max);
        self.i5min = self.i5min.min(o.i5min);
        self.i5max = self.i5max.max(o.i5max);
    }

    /// Take in the invariants I1, I2, J (and I4, I5 with a fibre) of one sample point.
    fn add(&mut self, i1: f64, i2: f64, j: f64, fibre: Option<(f64, f64)>) {
        if let Some((i4, i5)) = fibre {
            self.i4min = self.i4min.min(i4);
            self.i4max = self.i4max.max(i4);
            self.i5min = self.i5min.min(i5);
            self.i5max = self.i5max.max(i5);
        }
        self.i1min = self.i1min.min(i1);
        self.i1max = self.i1max.max(i1);
        self.i2min = self.i2min.min(i2);
        self.i2max = self.i2max.max(i2);
        self.jmin = self.jmin.min(j);
        self.jmax = self.jmax.max(j);
        self.jabsmax = self.jabsmax.max(j.abs());
    }

    /// Q1..Q5 from the extremes (Q4, Q5 NaN without a fibre; invalid if the geometry is not finite).
    fn quality(&self, with_fibre: bool) -> ElementQuality {
        let Extremes { i1min, i1max, i2min, i2max, jmin, jmax, jabsmax, i4min, i4max, i5min, i5max } = *self;
        let q3 = if jmin > 0.0 {
            jmin / jmax
        } else if jabsmax > 0.0 {
            jmin / jabsmax
        } else {
            -1.0
        };
        let ratio = |lo: f64, hi: f64| if hi > 0.0 { (lo / hi).sqrt() } else { 0.0 };
        let (q4, q5) = if with_fibre { (ratio(i4min, i4max), ratio(i5min, i5max)) } else { (f64::NAN, f64::NAN) };
        let q = ElementQuality { q1: ratio(i1min, i1max), q2: ratio(i2min, i2max), q3, q4, q5 };
        if q.q1.is_nan() || q.q2.is_nan() || q.q3.is_nan() {
            // Non-finite geometry: report as invalid rather than propagate NaN.
            return ElementQuality { q1: 0.0, q2: 0.0, q3: -1.0, q4, q5 };
        }
        q
    }
}

/// I1 = F:F and I2 = H:H (H = cof F) of the `dim` × `dim` gradient `f`.
fn strain_invariants(dim: usize, f: &linalg::Mat3) -> (f64, f64) {
    let h = linalg::cofactor(dim, f);
    let (mut i1, mut i2) = (0.0, 0.0);
    for i in 0..dim {
        for j in 0..dim {
            i1 += f[i][j] * f[i][j];
            i2 += h[i][j] * h[i][j];
        }
    }
    (i1, i2)
}

/// I4 = FN·FN and I5 = FᵀFN·FᵀFN for the unit fibre N (2D: in-plane part of N; F33 = 1).
fn fibre_invariants(dim: usize, f: &linalg::Mat3, n: &[f64; 3]) -> (f64, f64) {
    let mut fn_ = [0.0; 3];
    for i in 0..dim {
        fn_[i] = (0..dim).map(|k| f[i][k] * n[k]).sum();
    }
    if dim == 2 {
        fn_[2] = n[2];
    }
    let i4: f64 = fn_.iter().map(|v| v * v).sum();
    let mut ftfn = [0.0; 3];
    for i in 0..dim {
        ftfn[i] = (0..dim).map(|k| f[k][i] * fn_[k]).sum();
    }
    if dim == 2 {
        ftfn[2] = fn_[2];
    }
    let i5: f64 = ftfn.iter().map(|v| v * v).sum();
    (i4, i5)
}

/// Quality of every cell of a mesh given its coordinates and connectivity,
/// against the `straight` mesh (same nodes and cells, straight-sided
/// positions; None: the straight elements through the curved vertices), and
/// per-cell fibres for Q4, Q5.
pub fn cell_qualities(
    cache: &ElementCache,
    coords: &[f64],
    straight: Option<&[f64]>,
    cells: &[usize],
    fibres: Option<&[[f64; 3]]>,
) -> Vec<ElementQuality> {
    let (npc, dim) = (cache.n_basis, cache.dim);
    let fibre = |c: usize| fibres.map(|f| &f[c]);
    let Some(straight) = straight else {
        return map_cells(coords, cells, npc, dim, |c, xe, _| element_quality(cache, xe, xe, fibre(c)));
    };
    cells
        .par_chunks_exact(npc)
        .enumerate()
        .map_init(
            || (vec![0.0; npc * dim], vec![0.0; npc * dim]),
            |(xe, xs), (c, cell)| {
                gather_into(coords, cell, dim, xe);
                gather_into(straight, cell, dim, xs);
                element_quality(cache, xe, xs, fibre(c))
            },
        )
        .collect()
}

/// `f(c, xe, scratch)` for every cell c (in parallel, in order), xe being
/// its node coordinates gathered from `coords`, with a scratch vector per
/// thread.
fn map_cells<T: Send>(
    coords: &[f64],
    cells: &[usize],
    npc: usize,
    dim: usize,
    f: impl Fn(usize, &[f64], &mut Vec<f64>) -> T + Sync + Send,
) -> Vec<T> {
    cells
        .par_chunks_exact(npc)
        .enumerate()
        .map_init(
            || (vec![0.0; npc * dim], Vec::new()),
            |(xe, scratch), (c, cell)| {
                gather_into(coords, cell, dim, xe);
                f(c, xe, scratch)
            },
        )
        .collect()
}

/// Certified det J bounds of every cell ([`certified`]), any order.
pub fn certify_cells(basis: &LagrangeBasis, coords: &[f64], cells: &[usize]) -> Vec<CertifiedJacobian> {
    JacobianBernstein::new(basis).certify_cells(coords, cells)
}

impl JacobianBernstein {
    /// [`JacobianBernstein::certify`] on every cell of the mesh (`coords`,
    /// `cells` in this expansion's basis), in parallel.
    pub fn certify_cells(&self, coords: &[f64], cells: &[usize]) -> Vec<CertifiedJacobian> {
        let (npc, dim) = (self.n_nodes(), self.dim());
        map_cells(coords, cells, npc, dim, |_, xe, _| self.certify(xe))
    }
}

/// The checks of adaptive load stepping after an increment ([`crate::curve`]).
///
/// *Certified*: [`JacobianBernstein::certify`], det J ≤ 0 somewhere in the
/// element (an [`Verdict::Uncertain`] cell is not counted), at every order.
/// *Sampled*: det J ≤ 0 at a point of the quadrature rule of degree 2p, the
/// points the assembly sees.
pub struct ValidityCheck {
    basis: LagrangeBasis,
    certified: JacobianBernstein,
    points: ElementCache,
    /// Per basis function N_a, the largest |∇_ξ N_a| at the sample points.
    gradient_bounds: Vec<f64>,
}

/// A sampled margin below this fraction of the cell's largest ‖J‖_F at the
/// sample points is dropped: such a cell is always evaluated
/// ([`SampledMargins`]). A skipped cell then has σ_min(J) ≥ margin/2 ≥
/// ‖J‖₂ · MARGIN_FLOOR/3 at every sample point (‖J‖₂ grew by at most β), so
/// det J ≥ σ_min³ ≥ 3.7e-11 ‖J‖₂³, far above the round-off of its
/// computation (about 10 ε ‖J‖₂³ = 2.2e-15 ‖J‖₂³): the full check would find
/// it positive too.
const MARGIN_FLOOR: f64 = 1e-3;

/// What the sampled check keeps between calls to skip the cells that have
/// barely moved ([`ValidityCheck::invalid_cells_screened`]): per cell, its
/// node coordinates when last evaluated (its anchor) and a lower bound of
/// the smallest singular value of J = ∂x/∂ξ at the sample points there
/// (its margin; 0 until evaluated, or when invalid).
#[derive(Debug, Clone, Default)]
pub struct SampledMargins {
    anchors: Vec<f64>,
    margins: Vec<f64>,
}

impl ValidityCheck {
    pub fn new(basis: LagrangeBasis) -> ValidityCheck {
        let certified = JacobianBernstein::new(&basis);
        let points = ElementCache::new(&basis, &simplex_rule(basis.simplex(), 2 * basis.order()));
        let (n, d) = (points.n_basis, points.dim);
        let gradient_bounds = (0..n)
            .map(|a| {
                (0..points.n_points())
                    .map(|q| points.ref_grads[(q * n + a) * d..][..d].iter().map(|g| g * g).sum::<f64>().sqrt())
                    .fold(0.0, f64::max)
            })
            .collect();
        ValidityCheck { basis, certified, points, gradient_bounds }
    }

    /// Whether the cell with node coordinates `xe` is invalid at the sample
    /// points, as [`Self::sampled_invalid`] finds, and its margin
    /// ([`SampledMargins`]), from its Jacobians there (into `jac`):
    /// |det J| / ‖cof J‖_F in 3D (the largest singular value of cof J is
    /// σ₁σ₂) and |det J| / ‖J‖_F in 2D, at the worst point; 0 when the cell
    /// is invalid or that is below [`MARGIN_FLOOR`] times the largest ‖J‖_F.
    fn sampled_with_margin<const D: usize>(&self, xe: &[f64], jac: &mut Vec<f64>) -> (bool, f64) {
        let nq = self.points.n_points();
        crate::linalg::with_avx2(
            #[inline(always)]
            || self.points.by_point.jacobians_into::<D>(xe, jac),
        );
        let frobenius = |m: &linalg::Mat3| m.iter().flatten().map(|v| v * v).sum::<f64>().sqrt();
        let (mut margin, mut largest) = (f64::INFINITY, 0.0f64);
        for q in 0..nq {
            let j = mapping::jacobian_at::<D>(jac, nq, q);
            let det = linalg::det(D, &j);
            if det.is_nan() || det <= 0.0 {
                return (true, 0.0);
            }
            let size = frobenius(&j);
            let product = if D == 2 { size } else { frobenius(&linalg::cofactor(3, &j)) };
            margin = margin.min(det / product);
            largest = largest.max(size);
        }
        // Also 0 for a NaN margin.
        (false, if margin > MARGIN_FLOOR * largest { margin } else { 0.0 })
    }

    /// The sampled [`Self::invalid_cells`] (the same cells), skipping those
    /// that `margins` prove valid, and taking the margins of the others on
    /// `coords`; also returns how many cells were skipped.
    ///
    /// With d_a the displacement of a cell's node a from the cell's anchor
    /// less the mean of its nodes' (the gradients sum to zero),
    /// J − J_anchor = Σ_a d_a ∇N_aᵀ at each sample point, so
    /// ‖J − J_anchor‖₂ ≤ β = Σ_a |d_a| max |∇N_a|, and σ_min(J) ≥ margin − β
    /// (Weyl). A margin above 2β keeps J non-singular all the way from the
    /// anchor, so det J stays positive at every sample point, and well above
    /// round-off.
    pub fn invalid_cells_screened(
        &self,
        coords: &[f64],
        cells: &[usize],
        margins: &mut SampledMargins,
    ) -> (Vec<usize>, usize) {
        let (npc, dim) = (self.basis.len(), self.basis.simplex().dim());
        margins.margins.resize(cells.len() / npc, 0.0);
        margins.anchors.resize(cells.len() * dim, 0.0);
        let found: Vec<(Option<usize>, bool)> = cells
            .par_chunks_exact(npc)
            .zip(margins.anchors.par_chunks_exact_mut(npc * dim))
            .zip(margins.margins.par_iter_mut())
            .enumerate()
            .map_init(Vec::new, |jac, (c, ((cell, anchor), margin))| {
                if *margin > 2.0 * self.displacement_bound(coords, anchor, cell, dim) {
                    return (None, true);
                }
                gather_into(coords, cell, dim, anchor);
                let invalid;
                (invalid, *margin) = match dim {
                    2 => self.sampled_with_margin::<2>(anchor, jac),
                    _ => self.sampled_with_margin::<3>(anchor, jac),
                };
                (invalid.then_some(c), false)
            })
            .collect();
        let skipped = found.iter().filter(|(_, s)| *s).count();
        (found.into_iter().filter_map(|(c, _)| c).collect(), skipped)
    }

    /// β of [`Self::invalid_cells_screened`] for the cell with nodes `cell`
    /// and anchor coordinates `anchor`.
    fn displacement_bound(&self, coords: &[f64], anchor: &[f64], cell: &[usize], dim: usize) -> f64 {
        let moved = |a: usize, n: usize, i: usize| coords[n * dim + i] - anchor[a * dim + i];
        let mut mean = [0.0; 3];
        for (a, &n) in cell.iter().enumerate() {
            for (i, m) in mean.iter_mut().enumerate().take(dim) {
                *m += moved(a, n, i);
            }
        }
        mean.iter_mut().for_each(|m| *m /= cell.len() as f64);
        cell.iter()
            .enumerate()
            .zip(&self.gradient_bounds)
            .map(|((a, &n), g)| g * (0..dim).map(|i| (moved(a, n, i) - mean[i]).powi(2)).sum::<f64>().sqrt())
            .sum()
    }

    /// Whether the element with node coordinates `xe` is invalid.
    pub fn element_is_invalid(&self, xe: &[f64], certified: bool) -> bool {
        if certified {
            return self.certified.certify(xe).verdict == Verdict::Invalid;
        }
        self.sampled_invalid(xe, &mut Vec::new())
    }

    /// det J ≤ 0 (or NaN) at one of the sample points, from the Jacobians
    /// at all of them at once ([`mapping::PointGradients::jacobians_into`],
    /// into `jac`): the entries, and so the determinants, are bitwise those
    /// of [`mapping::jacobian`] point by point, at about a third of its time.
    fn sampled_invalid(&self, xe: &[f64], jac: &mut Vec<f64>) -> bool {
        match self.basis.simplex().dim() {
            2 => self.sampled_invalid_in::<2>(xe, jac),
            _ => self.sampled_invalid_in::<3>(xe, jac),
        }
    }

    fn sampled_invalid_in<const D: usize>(&self, xe: &[f64], jac: &mut Vec<f64>) -> bool {
        let nq = self.points.n_points();
        crate::linalg::with_avx2(
            #[inline(always)]
            || self.points.by_point.jacobians_into::<D>(xe, jac),
        );
        (0..nq).any(|q| {
            let j = linalg::det(D, &mapping::jacobian_at::<D>(jac, nq, q));
            j.is_nan() || j <= 0.0
        })
    }

    /// The certified bounds of every cell ([`certify_cells`]).
    pub fn certify_cells(&self, coords: &[f64], cells: &[usize]) -> Vec<CertifiedJacobian> {
        self.certified.certify_cells(coords, cells)
    }

    /// Indices of the invalid cells of the mesh (`coords`, `cells`), in order.
    pub fn invalid_cells(&self, coords: &[f64], cells: &[usize], certified: bool) -> Vec<usize> {
        let (npc, dim) = (self.basis.len(), self.basis.simplex().dim());
        let invalid = |xe: &[f64], jac: &mut Vec<f64>| match certified {
            true => self.element_is_invalid(xe, true),
            false => self.sampled_invalid(xe, jac),
        };
        map_cells(coords, cells, npc, dim, |c, xe, jac| invalid(xe, jac).then_some(c)).into_iter().flatten().collect()
    }

    /// Whether the cell with node indices `cell` is invalid on `coords`.
    pub fn cell_is_invalid(&self, coords: &[f64], cell: &[usize], certified: bool) -> bool {
        let dim = self.basis.simplex().dim();
        let mut xe = vec![0.0; cell.len() * dim];
        gather_into(coords, cell, dim, &mut xe);
        self.element_is_invalid(&xe, certified)
    }
}

fn gather_into(coords: &[f64], cell: &[usize], dim: usize, xe: &mut [f64]) {
    for (a, &n) in cell.iter().enumerate() {
        xe[a * dim..(a + 1) * dim].copy_from_slice(&coords[n * dim..(n + 1) * dim]);
    }
}

/// Add the certified figures of `cells` to `m`.
pub fn add_certified(m: &mut MeshQuality, cells: &[CertifiedJacobian]) {
    m.certified_min_q3 = cells.iter().map(CertifiedJacobian::q3_lower).fold(f64::INFINITY, f64::min);
    m.n_certified_invalid = cells.iter().filter(|c| c.verdict == Verdict::Invalid).count();
    m.n_uncertain = cells.iter().filter(|c| c.verdict == Verdict::Uncertain).count();
}

/// Reduce element qualities to the mesh figures.
pub fn summarize(q: &[ElementQuality]) -> MeshQuality {
    let mut m = MeshQuality {
        min_q1: f64::INFINITY,
        min_q2: f64::INFINITY,
        min_q3: f64::INFINITY,
        min_q4: f64::NAN,
        min_q5: f64::NAN,
        mean_q3: 0.0,
        n_invalid: 0,
        worst_cell: 0,
        histogram: [0; HISTOGRAM_BINS],
        certified_min_q3: f64::NAN,
        n_certified_invalid: 0,
        n_uncertain: 0,
    };
    for (c, e) in q.iter().enumerate() {
        m.min_q1 = m.min_q1.min(e.q1);
        m.min_q2 = m.min_q2.min(e.q2);
        // f64::min ignores NaN, so these stay NaN only when no cell has Q4/Q5.
        m.min_q4 = m.min_q4.min(e.q4);
        m.min_q5 = m.min_q5.min(e.q5);
        if e.q3 < m.min_q3 {
            m.min_q3 = e.q3;
            m.worst_cell = c;
        }
        m.mean_q3 += e.q3;
        if e.is_valid() {
            let bin = ((e.q3 * HISTOGRAM_BINS as f64) as usize).min(HISTOGRAM_BINS - 1);
            m.histogram[bin] += 1;
        } else {
            m.n_invalid += 1;
        }
    }
    if !q.is_empty() {
        m.mean_q3 /= q.len() as f64;
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::{LagrangeBasis, NodeSet, NodeSpacing, Simplex};

    /// Uniform numbers in [-0.5, 0.5) from `seed` (a 64-bit LCG's top 53 bits).
    fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    /// [`element_quality`] as it was computed point by point, ∂x/∂ξ from
    /// [`mapping::jacobian`] at each point.
    fn quality_point_by_point(
        cache: &ElementCache,
        xe: &[f64],
        xs: &[f64],
        fibre: Option<&[f64; 3]>,
    ) -> ElementQuality {
        let dim = cache.dim;
        let (jx_inv, _) = mapping::straight_inverse(dim, xs);
        let mut ext = Extremes::new();
        for q in 0..cache.n_points() {
            let dxdxi = mapping::jacobian(dim, xe, cache.grads_at(q));
            let f = linalg::matmul(dim, &dxdxi, &jx_inv);
            let (i1, i2) = strain_invariants(dim, &f);
            ext.add(i1, i2, linalg::det(dim, &dxdxi), fibre.map(|n| fibre_invariants(dim, &f, n)));
        }
        ext.quality(fibre.is_some())
    }

    #[test]
    fn the_jacobians_summed_in_lanes_give_bitwise_the_quality_of_the_point_by_point_ones() {
        let bits = |q: ElementQuality| [q.q1, q.q2, q.q3, q.q4, q.q5].map(f64::to_bits);
        let mut next = uniform(0x853c_49e6_748f_ea9bu64);
        for simplex in [Simplex::Tri, Simplex::Tet] {
            // Sample points 9 + 3 .. 343 + 286: every remainder of the chunks of 8 and more.
            for p in 1..=5 {
                let nodes = NodeSet::new(simplex, p, NodeSpacing::Optimal);
                let cache = sampling_cache(&LagrangeBasis::new(&nodes));
                let dim = simplex.dim();
                let xs: Vec<f64> = nodes.coords.iter().flat_map(|c| c[..dim].to_vec()).collect();
                // Mild, strong (inverted somewhere) and non-finite perturbations.
                for amplitude in [0.05, 0.8, f64::NAN] {
                    let xe: Vec<f64> = xs.iter().map(|x| x + amplitude * next()).collect();
                    for fibre in [None, Some(&[0.6, 0.0, 0.8])] {
                        let (fast, slow) =
                            (element_quality(&cache, &xe, &xs, fibre), quality_point_by_point(&cache, &xe, &xs, fibre));
                        assert_eq!(
                            bits(fast),
                            bits(slow),
                            "{simplex:?} p={p} amplitude {amplitude}: {fast:?} vs {slow:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_sampled_check_finds_what_det_j_point_by_point_finds() {
        let mut next = uniform(0x2545_f491_4f6c_dd1du64);
        let (mut valid, mut invalid) = (0, 0);
        for simplex in [Simplex::Tri, Simplex::Tet] {
            for p in 1..=5 {
                let nodes = NodeSet::new(simplex, p, NodeSpacing::Optimal);
                let check = ValidityCheck::new(LagrangeBasis::new(&nodes));
                let dim = simplex.dim();
                let xs: Vec<f64> = nodes.coords.iter().flat_map(|c| c[..dim].to_vec()).collect();
                for amplitude in [0.0, 0.05, 0.3, 0.8, 1.5, f64::NAN] {
                    for _ in 0..4 {
                        let xe: Vec<f64> = xs.iter().map(|x| x + amplitude * next()).collect();
                        let slow = (0..check.points.n_points()).any(|q| {
                            let j = linalg::det(dim, &mapping::jacobian(dim, &xe, check.points.grads_at(q)));
                            j.is_nan() || j <= 0.0
                        });
                        assert_eq!(
                            check.element_is_invalid(&xe, false),
                            slow,
                            "{simplex:?} p={p} amplitude {amplitude}"
                        );
                        let cells: Vec<usize> = (0..xe.len() / dim).collect();
                        assert_eq!(check.invalid_cells(&xe, &cells, false), if slow { vec![0] } else { vec![] });
                        if slow {
                            invalid += 1;
                        } else {
                            valid += 1;
                        }
                    }
                }
            }
        }
        // Both verdicts were met.
        assert!(valid > 20 && invalid > 20, "{valid} valid, {invalid} invalid");
    }

    /// The smallest singular value of the leading `dim` block of `j`, by
    /// inverse power iteration on JᵀJ.
    fn smallest_singular_value(dim: usize, j: &linalg::Mat3) -> f64 {
        let mut jtj = [[0.0; 3]; 3];
        for a in 0..dim {
            for b in 0..dim {
                jtj[a][b] = (0..dim).map(|k| j[k][a] * j[k][b]).sum();
            }
        }
        let (inv, _) = linalg::inverse(dim, &jtj);
        let mut v = [1.0, 0.7, 0.4];
        let mut largest = 0.0;
        for _ in 0..2000 {
            let w: Vec<f64> = (0..dim).map(|a| (0..dim).map(|b| inv[a][b] * v[b]).sum()).collect();
            largest = (0..dim).map(|a| w[a] * w[a]).sum::<f64>().sqrt();
            for a in 0..dim {
                v[a] = w[a] / largest;
            }
        }
        (1.0 / largest).sqrt()
    }

    #[test]
    fn a_sampled_margin_lies_between_the_smallest_singular_value_over_root_d_and_it() {
        let mut next = uniform(0x9e37_79b9_7f4a_7c15u64);
        for simplex in [Simplex::Tri, Simplex::Tet] {
            for p in 1..=4 {
                let nodes = NodeSet::new(simplex, p, NodeSpacing::Optimal);
                let check = ValidityCheck::new(LagrangeBasis::new(&nodes));
                let dim = simplex.dim();
                let xs: Vec<f64> = nodes.coords.iter().flat_map(|c| c[..dim].to_vec()).collect();
                let cells: Vec<usize> = (0..xs.len() / dim).collect();
                for (amplitude, stretch) in [(0.0, 1.0), (0.03, 1.0), (0.05, 0.01), (0.05, 3.0)] {
                    let xe: Vec<f64> = xs
                        .iter()
                        .enumerate()
                        .map(|(k, x)| if k % dim == 0 { stretch } else { 1.0 } * (x + amplitude * next()))
                        .collect();
                    let mut margins = SampledMargins::default();
                    assert_eq!(check.invalid_cells_screened(&xe, &cells, &mut margins), (vec![], 0));
                    let margin = margins.margins[0];
                    let smallest = (0..check.points.n_points())
                        .map(|q| smallest_singular_value(dim, &mapping::jacobian(dim, &xe, check.points.grads_at(q))))
                        .fold(f64::INFINITY, f64::min);
                    assert!(margin > 0.0, "{simplex:?} p={p} amplitude {amplitude}");
                    assert!(margin <= smallest * (1.0 + 1e-9), "{simplex:?} p={p}: {margin} > {smallest}");
                    assert!(
                        margin >= smallest / (dim as f64).sqrt() * (1.0 - 1e-9),
                        "{simplex:?} p={p}: {margin} vs {smallest}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_screened_sampled_check_finds_the_cells_of_the_full_one_and_skips_the_barely_moved() {
        let mut next = uniform(0xda94_2042_e4dd_58b5u64);
        for simplex in [Simplex::Tri, Simplex::Tet] {
            for p in 1..=4 {
                let nodes = NodeSet::new(simplex, p, NodeSpacing::Optimal);
                let check = ValidityCheck::new(LagrangeBasis::new(&nodes));
                let dim = simplex.dim();
                let npc = nodes.coords.len();
                // Disjoint cells, each a perturbed copy of the reference one
                // moved by its own amplitude; -1: translated, -2: mirrored.
                let amplitudes = [0.0, 1e-4, 1e-3, 1e-2, 0.1, 0.3, 0.8, 1.5, -1.0, -2.0];
                let mut anchor = Vec::new();
                let mut coords = Vec::new();
                for (c, &amplitude) in amplitudes.iter().cycle().take(4 * amplitudes.len()).enumerate() {
                    let scale = [1.0, 0.1, 2.0, 0.5][c % 4];
                    for (k, x) in nodes.coords.iter().flat_map(|x| x[..dim].to_vec()).enumerate() {
                        let a = scale * x + 0.03 * scale * next();
                        anchor.push(a);
                        coords.push(match amplitude {
                            -1.0 => a + 10.0,
                            -2.0 if k % dim == 0 => -a,
                            -2.0 => a,
                            _ => a + amplitude * scale * next(),
                        });
                    }
                }
                let cells: Vec<usize> = (0..anchor.len() / dim).collect();
                let n_cells = cells.len() / npc;
                // The first call evaluates every cell and anchors it.
                let mut margins = SampledMargins::default();
                assert_eq!(check.invalid_cells_screened(&anchor, &cells, &mut margins), (vec![], 0));
                assert!(margins.margins.iter().all(|&m| m > 0.0), "{simplex:?} p={p}: {margins:?}");
                let (screened, skipped) = check.invalid_cells_screened(&coords, &cells, &mut margins);
                let full = check.invalid_cells(&coords, &cells, false);
                assert_eq!(screened, full, "{simplex:?} p={p}");
                assert!(!full.is_empty(), "{simplex:?} p={p}: no cell inverted");
                // The unmoved, the translated and the least moved cells at
                // least; never an inverted one, nor the most moved.
                assert!(skipped >= 3 * 4 && skipped < n_cells - full.len(), "{simplex:?} p={p}: {skipped} skipped");
                // The cells evaluated were anchored where they are now: on
                // the same geometry, only the invalid ones are evaluated again.
                let (again, skipped) = check.invalid_cells_screened(&coords, &cells, &mut margins);
                assert_eq!(again, full, "{simplex:?} p={p}");
                assert_eq!(skipped, n_cells - full.len(), "{simplex:?} p={p}");
            }
        }
    }

    fn p2_triangle(delta: f64) -> (ElementCache, Vec<f64>) {
        let nodes = NodeSet::new(Simplex::Tri, 2, NodeSpacing::Optimal);
        let cache = sampling_cache(&LagrangeBasis::new(&nodes));
        // Straight nodes, then move the midpoint of edge (1,2) by δ(1,1):
        // x = ξ + 4δξη, y = η + 4δξη, so J = 1 + 4δ(ξ + η).
        let mut xe = Vec::new();
        for (m, x) in nodes.multi.iter().zip(&nodes.coords) {
            let moved = if m[1] == 1 && m[2] == 1 { delta } else { 0.0 };
            xe.extend_from_slice(&[x[0] + moved, x[1] + moved]);
        }
        (cache, xe)
    }

    #[test]
    fn straight_elements_have_unit_quality() {
        for simplex in [Simplex::Tri, Simplex::Tet] {
            let nodes = NodeSet::new(simplex, 3, NodeSpacing::Optimal);
            let cache = sampling_cache(&LagrangeBasis::new(&nodes));
            // An affine image of the reference element.
            let xe: Vec<f64> = nodes
                .coords
                .iter()
                .flat_map(|x| {
                    let y = [2.0 * x[0] + 0.5 * x[1], 0.3 * x[0] + 1.5 * x[1] - 0.2 * x[2], x[2] + 0.1 * x[0]];
                    y[..simplex.dim()].to_vec()
                })
                .collect();
            let q = element_quality(&cache, &xe, &xe, None);
            for v in [q.q1, q.q2, q.q3] {
                assert!((v - 1.0).abs() < 1e-12, "{simplex:?}: {q:?}");
            }
        }
    }

    #[test]
    fn q1_q2_are_measured_against_the_straight_element_not_the_curved_vertices() {
        // Straight element X = the reference tet; the curving moved its
        // vertices (x = Aξ at the vertices) and bent an edge (a bump on one
        // mid-edge node), so F = (∂x/∂ξ)(∂X/∂ξ)⁻¹ = ∂x/∂ξ. Against the straight
        // tet through the curved vertices, F would be (∂x/∂ξ) A⁻¹ instead.
        let nodes = NodeSet::new(Simplex::Tet, 2, NodeSpacing::Optimal);
        let cache = sampling_cache(&LagrangeBasis::new(&nodes));
        let a = [[1.0, 0.6, 0.0], [0.0, 0.5, 0.0], [0.2, 0.0, 1.3]];
        let xs: Vec<f64> = nodes.coords.iter().flat_map(|x| *x).collect();
        let mut xe: Vec<f64> =
            nodes.coords.iter().flat_map(|x| a.map(|r| r[0] * x[0] + r[1] * x[1] + r[2] * x[2])).collect();
        let mid = nodes.index_of(&[1, 1, 0, 0]).unwrap();
        xe[3 * mid + 1] += 0.08;
        let (mut i1, mut i2) = (Vec::new(), Vec::new());
        for q in 0..cache.n_points() {
            let f = mapping::jacobian(3, &xe, cache.grads_at(q));
            let h = linalg::cofactor(3, &f);
            i1.push(f.iter().flatten().map(|v| v * v).sum::<f64>());
            i2.push(h.iter().flatten().map(|v| v * v).sum::<f64>());
        }
        let ratio = |v: &[f64]| {
            let (lo, hi) = v.iter().fold((f64::INFINITY, 0.0f64), |(l, h), &x| (l.min(x), h.max(x)));
            (lo / hi).sqrt()
        };
        let (q1, q2) = (ratio(&i1), ratio(&i2));
        let against_straight = element_quality(&cache, &xe, &xs, None);
        let against_curved_vertices = element_quality(&cache, &xe, &xe, None);
        println!("Q1 {q1:.6}, Q2 {q2:.6}; against the curved vertices {against_curved_vertices:?}");
        assert!(
            (against_straight.q1 - q1).abs() < 1e-12 && (against_straight.q2 - q2).abs() < 1e-12,
            "{against_straight:?}"
        );
        assert!((against_curved_vertices.q1 - q1).abs() > 1e-3, "the reference should matter here");
        assert!((against_straight.q3 - against_curved_vertices.q3).abs() < 1e-12, "Q3 does not depend on X");
        // An affine map of the straight element: constant F, so Q1 = Q2 = 1
        // whichever the reference (the measures see variation of F, not F − I).
        let affine: Vec<f64> =
            nodes.coords.iter().flat_map(|x| a.map(|r| r[0] * x[0] + r[1] * x[1] + r[2] * x[2])).collect();
        let q = element_quality(&cache, &affine, &xs, None);
        assert!((q.q1 - 1.0).abs() < 1e-12 && (q.q2 - 1.0).abs() < 1e-12, "{q:?}");
    }

    #[test]
    fn curved_p2_triangle_scaled_jacobian_matches_analytic_bounds() {
        let delta = 0.1;
        let (cache, xe) = p2_triangle(delta);
        let q = element_quality(&cache, &xe, &xe, None);
        // J = 1 + 4δ(ξ+η) ranges over [1, 1 + 4δ], extremes at the vertex
        // (0,0) and on the edge ξ + η = 1, which the lattice samples.
        let expect = 1.0 / (1.0 + 4.0 * delta);
        assert!((q.q3 - expect).abs() < 1e-12, "{} vs {expect}", q.q3);
        assert!(q.q1 < 1.0 && q.q1 > 0.5);
        assert!((q.q1 - q.q2).abs() < 1e-14, "Q1 = Q2 in 2D");
    }

    #[test]
    fn folded_p2_triangle_is_invalid_and_counted() {
        let (cache, good) = p2_triangle(0.05);
        let (_, bad) = p2_triangle(-0.4);
        let qs = vec![element_quality(&cache, &good, &good, None), element_quality(&cache, &bad, &bad, None)];
        assert!(qs[1].q3 < 0.0);
        let m = summarize(&qs);
        assert_eq!(m.n_invalid, 1);
        assert_eq!(m.worst_cell, 1);
        assert_eq!(m.histogram.iter().sum::<usize>(), 1);
        assert!((m.mean_q3 - (qs[0].q3 + qs[1].q3) / 2.0).abs() < 1e-15);
    }
}
