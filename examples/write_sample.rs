//! Writes small straight-sided order-p meshes (two cells sharing a facet) as
//! .msh and .vtu, for `scripts/check_written_files.py` to open with gmsh and VTK.
//!
//! `cargo run --example write_sample -- OUT_DIR [ORDER...]` (default orders 3 and 6)
//! writes OUT_DIR/{tri,tet}_p{ORDER}.{msh,vtu}.

use hocurve::io::gmsh::write_msh;
use hocurve::io::vtk::write_vtu;
use hocurve::io::CellMeshView;
use hocurve::reference::Simplex;
use std::collections::HashMap;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().ok_or("usage: write_sample OUT_DIR [ORDER...]")?);
    let mut orders: Vec<usize> = args.map(|a| a.parse()).collect::<Result<_, _>>()?;
    if orders.is_empty() {
        orders = vec![3, 6];
    }
    std::fs::create_dir_all(&out)?;
    for p in orders {
        for simplex in [Simplex::Tri, Simplex::Tet] {
            let (coords, cells, multi) = sample(simplex, p);
            let view = CellMeshView { simplex, order: p, coords: &coords, cells: &cells, cell_multi: &multi };
            let name = format!("{}_p{p}", if simplex == Simplex::Tri { "tri" } else { "tet" });
            write_msh(&out.join(format!("{name}.msh")), &view)?;
            let ids: Vec<f64> = (0..view.n_cells()).map(|c| c as f64).collect();
            write_vtu(&out.join(format!("{name}.vtu")), &view, &[("x", &coords)], &[("cell_id", &ids)])?;
            println!("{name}: {} nodes, {} cells", view.n_nodes(), view.n_cells());
        }
    }
    Ok(())
}

/// Two positively oriented straight cells sharing a facet, with shared nodes
/// merged; the local order is the lexicographically sorted multi-index list
/// (neither gmsh's nor VTK's, so both writers must permute).
fn sample(simplex: Simplex, p: usize) -> (Vec<f64>, Vec<usize>, Vec<[usize; 4]>) {
    let cells_xyz: Vec<Vec<[f64; 3]>> = match simplex {
        Simplex::Tri => {
            vec![vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]], vec![[1., 0., 0.], [1., 1., 0.], [0., 1., 0.]]]
        }
        Simplex::Tet => vec![
            vec![[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]],
            vec![[1., 0., 0.], [0., 1., 0.], [0., 0., 1.], [1., 1., 1.]],
        ],
    };
    let mut multi = hocurve::reference::ordering::gmsh_multi_indices(simplex, p);
    multi.sort();
    let d = simplex.dim();
    let mut index: HashMap<[i64; 3], usize> = HashMap::new();
    let mut coords = Vec::new();
    let mut cells = Vec::new();
    for verts in &cells_xyz {
        for a in &multi {
            let mut x = [0.0; 3];
            for (v, &ai) in verts.iter().zip(a) {
                for c in 0..3 {
                    x[c] += ai as f64 / p as f64 * v[c];
                }
            }
            let key = x.map(|c| (c * p as f64).round() as i64);
            let next = index.len();
            let i = *index.entry(key).or_insert_with(|| {
                coords.extend_from_slice(&x[..d]);
                next
            });
            cells.push(i);
        }
    }
    (coords, cells, multi)
}
