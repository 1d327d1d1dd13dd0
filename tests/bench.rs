//! `hocurve bench` end to end: a minimal run of the built binary gives
//! well-formed rows (each case in its own child process), finite exponents
//! and a CSV with the same rows. Timings are not checked, only their form.

use std::process::Command;

#[test]
fn bench_minimal_run_prints_well_formed_rows_and_a_finite_exponent() {
    let dir = std::env::temp_dir().join(format!("hocurve-bench-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("bench.csv");
    let out = Command::new(env!("CARGO_BIN_EXE_hocurve"))
        .args(["bench", "--quick", "--dims", "2,3", "--orders", "3", "--max-dofs", "20000", "--csv"])
        .arg(&csv)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "stdout:\n{stdout}\nstderr:\n{}", String::from_utf8_lossy(&out.stderr));

    let mut lines = stdout.lines();
    let header: Vec<&str> = lines.next().unwrap().split_whitespace().collect();
    assert_eq!(header[..6], ["dim", "p", "size", "cells", "nodes", "unknowns"]);
    assert_eq!(*header.last().unwrap(), "status");
    let rows: Vec<Vec<&str>> =
        lines.by_ref().take_while(|l| !l.trim().is_empty()).map(|l| l.split_whitespace().collect()).collect();
    // 2D p=3: three sizes (7968, 12816, 18240 unknowns); 3D p=3: two (822, 7158).
    assert_eq!(rows.len(), 5, "{stdout}");
    let mut last = (0, 0);
    for r in &rows {
        assert_eq!(r.len(), header.len(), "{r:?}");
        assert_eq!(*r.last().unwrap(), "ok", "{r:?}");
        let (dim, unknowns): (usize, usize) = (r[0].parse().unwrap(), r[5].parse().unwrap());
        assert!(unknowns <= 20000 && unknowns > 0);
        if dim == last.0 {
            assert!(unknowns > last.1, "unknowns grow along a series: {r:?}");
        }
        last = (dim, unknowns);
        // The default choice: direct in 2D and for small 3D systems
        // (hocurve::solver::auto_direct_max_dofs: 5,000 at p = 3).
        if dim == 2 || unknowns <= 5000 {
            assert_eq!(r[6], "direct", "{r:?}");
            assert_eq!(r[7], "-", "no Krylov iterations for the direct solver");
        } else {
            assert_eq!(r[6], "pcg-pmg", "{r:?}");
            let iterations: f64 = r[7].parse().unwrap();
            assert!(iterations > 0.0 && iterations < 100.0, "{r:?}");
        }
        for (k, v) in r.iter().enumerate().take(17).skip(8) {
            let x: f64 = v.parse().unwrap_or_else(|_| panic!("column {} = '{v}' is not a number", header[k]));
            assert!(x.is_finite() && x >= -1.0, "column {} = {x}", header[k]);
        }
        let peak_mb: f64 = r[15].parse().unwrap();
        assert!(peak_mb > 1.0, "peak memory of the child is measured");
    }

    let mut lines = lines.skip_while(|l| !l.starts_with("dim")).skip(1);
    let exponents: Vec<Vec<&str>> =
        lines.by_ref().take_while(|l| !l.trim().is_empty()).map(|l| l.split_whitespace().collect()).collect();
    assert_eq!(exponents.len(), 2, "{stdout}");
    // Then the peak heap of each phase: one line per row, every phase measured.
    let memory: Vec<Vec<&str>> = lines
        .skip_while(|l| !l.trim_start().starts_with("dim"))
        .skip(1)
        .map(|l| l.split_whitespace().collect())
        .collect();
    assert_eq!(memory.len(), rows.len(), "{stdout}");
    for m in &memory {
        let heap: Vec<f64> = m[3..].iter().map(|v| v.parse().unwrap_or(f64::NAN)).collect();
        assert_eq!(heap.len(), 7, "six phases and KB per unknown: {m:?}");
        assert!(heap.iter().all(|h| h.is_finite() && *h > 0.0), "{m:?}");
        // The elastic stage holds the matrix: it needs more than the preparation.
        assert!(heap[3] > heap[0], "{m:?}");
    }
    let two_d = exponents.iter().find(|e| e[0] == "2" && e[1] == "3").unwrap();
    for v in &two_d[3..5] {
        let slope: f64 = v.parse().unwrap_or_else(|_| panic!("2D exponent '{v}' is not a number:\n{stdout}"));
        assert!(slope.is_finite());
    }

    let csv_text = std::fs::read_to_string(&csv).unwrap();
    let csv_rows: Vec<&str> = csv_text.lines().collect();
    assert_eq!(csv_rows.len(), 1 + rows.len());
    let n_cols = csv_rows[0].split(',').count();
    assert!(csv_rows.iter().all(|l| l.split(',').count() == n_cols), "{csv_text}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bench_rejects_a_bad_order_before_running() {
    let out = Command::new(env!("CARGO_BIN_EXE_hocurve")).args(["bench", "--orders", "2,11"]).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--orders"));
}

#[test]
fn bench_layers_compares_each_stretching_with_the_isotropic_mesh() {
    let out = Command::new(env!("CARGO_BIN_EXE_hocurve"))
        .args(["bench", "--layers", "--dims", "2", "--orders", "2"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "stdout:\n{stdout}\nstderr:\n{}", String::from_utf8_lossy(&out.stderr));
    let rows: Vec<Vec<&str>> = stdout
        .lines()
        .skip_while(|l| !l.starts_with("boundary layers"))
        .skip(2)
        .take_while(|l| !l.trim().is_empty())
        .map(|l| l.split_whitespace().collect())
        .collect();
    let stretchings: Vec<&str> = rows.iter().map(|r| r[2]).collect();
    assert_eq!(stretchings, ["1", "100", "300", "1000"], "{stdout}");
    for r in &rows {
        assert_eq!(r.len(), 10, "{r:?}");
        assert_eq!(r[3], rows[0][3], "the same mesh size at every stretching: {r:?}");
        let iterations: f64 = r[4].parse().unwrap_or_else(|_| panic!("PCG ran: {r:?}"));
        assert!(iterations > 0.0);
        assert_eq!(r[5], "0", "no fallback: {r:?}");
        let ratio: f64 = r[8].parse().unwrap();
        assert!((ratio - iterations / rows[0][4].parse::<f64>().unwrap()).abs() < 0.01, "{r:?}");
    }
    assert_eq!(rows[0][8], "1.00");
}
