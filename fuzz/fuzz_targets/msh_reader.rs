//! Fuzz target: bytes → the `.msh` reader and everything the CLI does with
//! what it reads, short of solving. Errors are fine; a panic, an abort, a
//! timeout or a memory error is a bug.
//!
//! Path 1 (`hocurve curve`): `parse_msh_bytes` → `to_linear_mesh` →
//! `Session::try_new` (validation, orientation, topology, boundary caps,
//! boundary classification), then for small meshes one run at p = 2 with a
//! projector that returns each point unchanged.
//! Path 2 (`hocurve quality`): `high_order_cells` → sampled and certified
//! quality, for small meshes of order ≤ 3.
#![no_main]

use std::cell::RefCell;
use std::collections::HashMap;

use hocurve::geometry::Projector;
use hocurve::io::gmsh::{high_order_cells, parse_msh_bytes, to_linear_mesh};
use hocurve::quality;
use hocurve::reference::{ordering, LagrangeBasis, NodeSet, NodeSpacing};
use hocurve::session::Session;
use libfuzzer_sys::fuzz_target;

/// Returns every point unchanged: a valid projector for any geometry.
struct Identity;

impl Projector for Identity {
    fn project(&self, _: usize, _: i32, points: &[[f64; 3]], out: &mut [[f64; 3]]) -> Result<(), String> {
        out.copy_from_slice(points);
        Ok(())
    }
}

thread_local! {
    /// Lagrange bases by (simplex, order): building one is costlier than a run.
    static BASES: RefCell<HashMap<(usize, usize), (LagrangeBasis, hocurve::mapping::ElementCache)>> =
        RefCell::new(HashMap::new());
}

fn curve_path(data: &[u8]) {
    let Ok(msh) = parse_msh_bytes(data) else { return };
    if let Ok(mesh) = to_linear_mesh(&msh) {
        if mesh.n_cells() <= 200 {
            if let Ok(mut session) = Session::try_new(mesh) {
                let small = session.mesh().n_cells() <= 12;
                session.set_projector(Some(Box::new(Identity)));
                if small && session.set_order(2, NodeSpacing::Optimal).is_ok() {
                    let before = session.mesh().coords.clone();
                    if session.run(1).is_err() {
                        assert_eq!(session.mesh().coords, before, "a failed run changed the mesh");
                    }
                }
            }
        }
    }
    quality_path(&msh);
}

fn quality_path(msh: &hocurve::io::gmsh::MshContent) {
    let Ok((simplex, order, coords, gmsh_cells)) = high_order_cells(msh) else { return };
    let npc = simplex.n_nodes(order);
    if order > 3 || gmsh_cells.len() / npc > 16 {
        return;
    }
    let nodes = NodeSet::new(simplex, order, NodeSpacing::Equispaced);
    let perm = ordering::permutation(&ordering::gmsh_multi_indices(simplex, order), &nodes.multi)
        .expect("gmsh ordering is a permutation of the node set");
    let cells: Vec<usize> = gmsh_cells.chunks_exact(npc).flat_map(|c| perm.iter().map(move |&k| c[k])).collect();
    BASES.with(|b| {
        let mut b = b.borrow_mut();
        let (basis, cache) = b.entry((simplex.dim(), order)).or_insert_with(|| {
            let basis = LagrangeBasis::new(&nodes);
            let cache = quality::sampling_cache(&basis);
            (basis, cache)
        });
        let mut q = quality::summarize(&quality::cell_qualities(cache, &coords, None, &cells, None));
        quality::add_certified(&mut q, &quality::certify_cells(basis, &coords, &cells));
    });
}

fuzz_target!(|data: &[u8]| {
    curve_path(data);
});
