//! The C ABI's calls for a mesh spread over MPI processes, in the library
//! built without MPI (the default): what they do without it. Under MPI they
//! are tested by tests/mpi/test_distributed.py.

use std::ptr::null_mut;

use hocurve::ffi::*;
use hocurve::mesh::LinearMesh;
use hocurve::session::Session;

const SQ: [f64; 8] = [0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0];
const SQ_CELLS: [i64; 6] = [0, 1, 2, 0, 2, 3];

#[cfg(not(feature = "mpi"))]
fn thread_error() -> String {
    unsafe { std::ffi::CStr::from_ptr(hoc_mesh_last_error(std::ptr::null())).to_string_lossy().into_owned() }
}

#[cfg(not(feature = "mpi"))]
#[test]
fn a_distributed_mesh_needs_a_library_built_with_mpi() {
    let ids = [10i64, 11, 12, 13];
    let mut m = std::ptr::dangling_mut::<HocMesh>();
    let status =
        unsafe { hoc_mesh_create_distributed(0, 2, 4, SQ.as_ptr(), ids.as_ptr(), 2, SQ_CELLS.as_ptr(), &mut m) };
    assert_eq!(status, HOC_ERROR_INVALID_ARGUMENT);
    assert!(m.is_null());
    assert!(thread_error().contains("built without MPI"), "{}", thread_error());
}

#[test]
fn a_whole_mesh_is_its_own_global_numbering_on_process_0() {
    unsafe {
        let mut m = null_mut();
        assert_eq!(hoc_mesh_create(2, 4, SQ.as_ptr(), 2, SQ_CELLS.as_ptr(), &mut m), HOC_OK);
        assert_eq!(hoc_mesh_set_order(m, 3, HOC_SPACING_OPTIMAL), HOC_OK);
        let mut n = 0;
        assert_eq!(hoc_mesh_node_count(m, &mut n), HOC_OK);
        let mut ids = vec![-1i64; n];
        let mut owners = vec![-1; n];
        assert_eq!(hoc_mesh_get_global_nodes(m, n, ids.as_mut_ptr(), owners.as_mut_ptr()), HOC_OK);
        assert_eq!(ids, (0..n as i64).collect::<Vec<_>>());
        assert!(owners.iter().all(|&o| o == 0));
        // Either array may be NULL; the count must be the node count.
        assert_eq!(hoc_mesh_get_global_nodes(m, n, null_mut(), owners.as_mut_ptr()), HOC_OK);
        assert_eq!(hoc_mesh_get_global_nodes(m, n + 1, ids.as_mut_ptr(), null_mut()), HOC_ERROR_BUFFER_SIZE);
        hoc_mesh_destroy(&mut m);
    }
}

#[test]
fn a_share_needs_one_distinct_global_id_per_vertex() {
    let square = || LinearMesh {
        dim: 2,
        coords: SQ.to_vec(),
        cells: SQ_CELLS.iter().map(|&v| v as usize).collect(),
        ..Default::default()
    };
    let e = Session::try_new_partition(square(), 0, vec![1, 2, 3]).err().expect("three ids for four vertices");
    assert!(e.to_string().contains("3 global ids for 4 vertices"), "{e}");
    let e = Session::try_new_partition(square(), 0, vec![1, 2, 3, 2]).err().expect("id 2 twice");
    assert!(e.to_string().contains("global id 2 is given to two vertices"), "{e}");
    let s = Session::try_new_partition(square(), 0, vec![7, 3, 5, 1]).expect("a share");
    let p = s.partition().expect("a share");
    assert_eq!(p.global_vertex, [7, 3, 5, 1]);
    assert!(p.nodes.is_none(), "global node indices come with a run");
}
