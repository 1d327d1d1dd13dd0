//! Small geometric helpers of the repair stage (3-vectors, z = 0 in 2D).

/// A facet as its sorted vertices (`usize::MAX` in the third slot in 2D).
pub type FacetKey = [usize; 3];

/// Key of the facet of `cell` (`dim + 1` vertices) opposite its local vertex `k`.
pub fn facet_of(cell: &[usize], k: usize) -> FacetKey {
    let mut key = [usize::MAX; 3];
    let mut i = 0;
    for (j, &v) in cell.iter().enumerate() {
        if j != k {
            key[i] = v;
            i += 1;
        }
    }
    key[..i].sort_unstable();
    key
}

/// Key of facet `f` (2 or 3 vertices).
pub fn facet_key(f: &[usize]) -> FacetKey {
    let mut k = [usize::MAX; 3];
    k[..f.len()].copy_from_slice(f);
    k[..f.len()].sort_unstable();
    k
}

pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub fn cross(u: [f64; 3], v: [f64; 3]) -> [f64; 3] {
    [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
}

pub fn dot(u: [f64; 3], v: [f64; 3]) -> f64 {
    u[0] * v[0] + u[1] * v[1] + u[2] * v[2]
}

pub fn norm(u: [f64; 3]) -> f64 {
    dot(u, u).sqrt()
}

/// dim! times the signed measure of the simplex `x[..=dim]`.
pub fn orient(dim: usize, x: &[[f64; 3]]) -> f64 {
    let (u, v) = (sub(x[1], x[0]), sub(x[2], x[0]));
    if dim == 2 {
        u[0] * v[1] - u[1] * v[0]
    } else {
        dot(cross(u, v), sub(x[3], x[0]))
    }
}

/// Barycentric coordinates of `p` in the simplex `x[..=dim]` (any orientation).
pub fn barycentric(dim: usize, x: &[[f64; 3]], p: [f64; 3]) -> [f64; 4] {
    let total = orient(dim, x);
    let mut l = [0.0; 4];
    for (k, lk) in l.iter_mut().enumerate().take(dim + 1) {
        let mut y = [x[0], x[1], x[2], if dim == 3 { x[3] } else { [0.0; 3] }];
        y[k] = p;
        *lk = orient(dim, &y) / total;
    }
    l
}

/// The facets of `mesh` that belong to one cell only (its boundary), sorted.
/// Counted by sorting the keys of all cell facets, not hashing them.
pub fn boundary_facets(mesh: &crate::mesh::LinearMesh) -> Vec<FacetKey> {
    use rayon::prelude::*;
    let d = mesh.dim;
    let mut all: Vec<FacetKey> =
        mesh.cells.par_chunks_exact(d + 1).flat_map_iter(|c| (0..=d).map(move |k| facet_of(c, k))).collect();
    all.par_sort_unstable();
    let mut out = Vec::new();
    let mut i = 0;
    while i < all.len() {
        let mut j = i + 1;
        while j < all.len() && all[j] == all[i] {
            j += 1;
        }
        if j == i + 1 {
            out.push(all[i]);
        }
        i = j;
    }
    out
}
