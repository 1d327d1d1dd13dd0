//! Regression tests of the C ABI called from Rust, for bugs found by the
//! bad-input catalogue and the fuzzers (`fuzz/`).

use std::ffi::CStr;
use std::ptr::null_mut;

use hocurve::ffi::*;

fn last_error(mesh: *const HocMesh) -> String {
    unsafe { CStr::from_ptr(hoc_mesh_last_error(mesh)).to_string_lossy().into_owned() }
}

const SQ: [f64; 8] = [0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0];
const SQ_CELLS: [i64; 6] = [0, 1, 2, 0, 2, 3];

/// A count claiming 2^40 items with a small buffer used to be read (past the
/// buffer) or allocated (aborting the process); it must fail first.
#[test]
fn enormous_counts_fail_before_the_buffers_are_read() {
    let big = 1usize << 40;
    let one = [0.0f64; 1];
    let idx = [0i64; 1];
    let tag = [1i32; 1];
    unsafe {
        let mut m = null_mut();
        for (nv, nc) in [(big, 2), (4, big), (usize::MAX, 2), (4, usize::MAX / 3)] {
            let x = if nv == 4 { SQ.as_ptr() } else { one.as_ptr() };
            let c = if nc == 2 { SQ_CELLS.as_ptr() } else { idx.as_ptr() };
            assert_eq!(hoc_mesh_create(2, nv, x, nc, c, &mut m), HOC_ERROR_INVALID_ARGUMENT);
            assert!(m.is_null());
            assert!(last_error(std::ptr::null()).contains("is too large"), "{}", last_error(std::ptr::null()));
        }
        assert_eq!(hoc_mesh_create(2, 4, SQ.as_ptr(), 2, SQ_CELLS.as_ptr(), &mut m), HOC_OK);
        assert_eq!(hoc_mesh_set_boundary(m, big, idx.as_ptr(), tag.as_ptr()), HOC_ERROR_INVALID_ARGUMENT);
        assert!(last_error(m).contains("n_facets = 1099511627776 is too large"), "{}", last_error(m));
        assert_eq!(hoc_mesh_set_feature_edges(m, big, idx.as_ptr(), tag.as_ptr()), HOC_ERROR_INVALID_ARGUMENT);
        assert!(last_error(m).contains("n_edges = 1099511627776 is too large"), "{}", last_error(m));
        hoc_mesh_destroy(&mut m);
    }
}

/// Fibres are per input cell: once a boundary cap was removed, no count was
/// accepted (the C layer wanted the current cells, the session the input ones).
#[test]
fn fibres_can_be_set_on_a_mesh_whose_caps_were_removed() {
    // A flat cap (0, 1, 2, 3) under a ridge 0-1, on two tets sharing 2-3-4 (see mesh/caps.rs).
    let x = [0.0, 0.0, 0.05, 1.0, 0.0, 0.05, 0.5, 1.0, 0.0, 0.5, -1.0, 0.0, 0.5, 0.0, -1.0];
    let cells = [0i64, 1, 2, 3, 0, 2, 3, 4, 1, 2, 3, 4];
    let facets = [0i64, 1, 2, 0, 1, 3, 0, 2, 4, 1, 2, 4, 0, 3, 4, 1, 3, 4];
    let tags = [1i32, 1, 2, 2, 3, 3];
    let fibres = [0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0];
    unsafe {
        let mut m = null_mut();
        assert_eq!(hoc_mesh_create(3, 5, x.as_ptr(), 3, cells.as_ptr(), &mut m), HOC_OK);
        assert_eq!(hoc_mesh_set_boundary(m, 6, facets.as_ptr(), tags.as_ptr()), HOC_OK);
        let (mut nc, mut npc) = (0, 0);
        assert_eq!(hoc_mesh_cell_count(m, &mut nc, &mut npc), HOC_OK);
        assert_eq!(nc, 2, "the cap is removed");
        assert_eq!(hoc_mesh_set_fibres(m, 2, fibres.as_ptr()), HOC_ERROR_BUFFER_SIZE);
        assert!(last_error(m).contains("created with 3 cells"), "{}", last_error(m));
        assert_eq!(hoc_mesh_set_fibres(m, 3, fibres.as_ptr()), HOC_OK, "{}", last_error(m));
        assert_eq!(hoc_mesh_set_remove_caps(m, 0), HOC_OK);
        assert_eq!(hoc_mesh_set_fibres(m, 3, fibres.as_ptr()), HOC_OK, "{}", last_error(m));
        hoc_mesh_destroy(&mut m);
    }
}

/// A zero or non-finite fibre direction was accepted by hoc_mesh_set_fibres
/// and only rejected by the next run (found by c_tests/t700-catalogue): the
/// call that set it must fail, and leave the earlier fibres in place.
#[test]
fn zero_or_non_finite_fibres_are_rejected_when_set() {
    let good = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    unsafe {
        let mut m = null_mut();
        assert_eq!(hoc_mesh_create(2, 4, SQ.as_ptr(), 2, SQ_CELLS.as_ptr(), &mut m), HOC_OK);
        assert_eq!(hoc_mesh_set_fibres(m, 2, good.as_ptr()), HOC_OK);
        for (k, bad) in
            [[0.0; 3], [f64::NAN, 0.0, 0.0], [f64::INFINITY, 0.0, 0.0], [1e200, 1e200, 0.0]].into_iter().enumerate()
        {
            let f = [good[0], good[1], good[2], bad[0], bad[1], bad[2]];
            assert_eq!(hoc_mesh_set_fibres(m, 2, f.as_ptr()), HOC_ERROR_INVALID_ARGUMENT, "case {k}");
            assert!(last_error(m).contains("fibre direction of cell 1 is zero or not finite"), "{}", last_error(m));
        }
        // The good fibres are still set: a transversely isotropic run works.
        assert_eq!(hoc_mesh_set_material(m, HOC_MATERIAL_TRANSVERSELY_ISOTROPIC_LINEAR, 1.0, 0.3), HOC_OK);
        assert_eq!(hoc_mesh_set_order(m, 2, HOC_SPACING_OPTIMAL), HOC_OK);
        assert_eq!(hoc_mesh_run_increments(m, 1), HOC_OK, "{}", last_error(m));
        hoc_mesh_destroy(&mut m);
    }
}
