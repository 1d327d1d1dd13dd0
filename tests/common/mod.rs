//! Small structured meshes made in the tests themselves.
#![allow(dead_code)]

use hocurve::mesh::LinearMesh;

/// Unit square split into 2n² triangles, interior vertices jittered
/// deterministically so the mesh is not trivially structured.
pub fn square_mesh(n: usize) -> LinearMesh {
    let mut coords = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (mut x, mut y) = (i as f64 / n as f64, j as f64 / n as f64);
            if i > 0 && i < n && j > 0 && j < n {
                x += 0.15 / n as f64 * ((i * 7 + j * 3) as f64).sin();
                y += 0.15 / n as f64 * ((i * 5 + j * 11) as f64).cos();
            }
            coords.extend_from_slice(&[x, y]);
        }
    }
    let v = |i: usize, j: usize| j * (n + 1) + i;
    let mut cells = Vec::new();
    for j in 0..n {
        for i in 0..n {
            cells.extend_from_slice(&[v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            cells.extend_from_slice(&[v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
        }
    }
    LinearMesh { dim: 2, coords, cells, ..Default::default() }
}

/// Unit cube split into 6n³ tetrahedra (Kuhn subdivision), interior vertices jittered.
pub fn cube_mesh(n: usize) -> LinearMesh {
    let mut coords = Vec::new();
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                let mut x = [i as f64 / n as f64, j as f64 / n as f64, k as f64 / n as f64];
                if [i, j, k].iter().all(|&t| t > 0 && t < n) {
                    for (d, xd) in x.iter_mut().enumerate() {
                        *xd += 0.1 / n as f64 * ((i * 7 + j * 3 + k * 5 + d * 13) as f64).sin();
                    }
                }
                coords.extend_from_slice(&x);
            }
        }
    }
    let v = |i: usize, j: usize, k: usize| (k * (n + 1) + j) * (n + 1) + i;
    let mut cells = Vec::new();
    // The six tets of the Kuhn subdivision share the main diagonal 0 → 7.
    let perms = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                for p in perms {
                    let mut c = [i, j, k];
                    let mut tet = vec![v(c[0], c[1], c[2])];
                    for &axis in &p {
                        c[axis] += 1;
                        tet.push(v(c[0], c[1], c[2]));
                    }
                    cells.extend_from_slice(&tet);
                }
            }
        }
    }
    LinearMesh { dim: 3, coords, cells, ..Default::default() }
}
