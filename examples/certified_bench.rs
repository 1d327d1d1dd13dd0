//! Time of the certified det J check ([`quality::certify_cells`]) on curved
//! sphere-cavity meshes, against the sampled qualities: medians of `reps`
//! runs per order.
//!
//! `cargo run --release --example certified_bench -- <n> <n_radial> <reps> <p>...`
//! (RAYON_NUM_THREADS=1 for the cost on one core.)

use std::time::Instant;

use hocurve::cases;
use hocurve::curve::{curve, CurveOptions, Formulation};
use hocurve::quality::{self, CertifiedJacobian, Verdict};
use hocurve::reference::{LagrangeBasis, NodeSet};

/// The certified bounds, whichever form `certify_cells` returns them in
/// (`Option<Vec<_>>` before every order was covered, `Vec<_>` after).
trait Bounds {
    fn bounds(&self) -> Option<&[CertifiedJacobian]>;
}

impl Bounds for Vec<CertifiedJacobian> {
    fn bounds(&self) -> Option<&[CertifiedJacobian]> {
        Some(self)
    }
}

impl Bounds for Option<Vec<CertifiedJacobian>> {
    fn bounds(&self) -> Option<&[CertifiedJacobian]> {
        self.as_deref()
    }
}

fn median(mut t: Vec<f64>) -> f64 {
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

fn main() -> hocurve::Result<()> {
    let a: Vec<String> = std::env::args().collect();
    let n: usize = a.get(1).map_or(1, |s| s.parse().expect("n"));
    let nr: usize = a.get(2).map_or(2, |s| s.parse().expect("n_radial"));
    let reps: usize = a.get(3).map_or(5, |s| s.parse().expect("reps"));
    let orders: Vec<usize> =
        if a.len() > 4 { a[4..].iter().map(|s| s.parse().expect("p")).collect() } else { vec![4, 8] };
    let case = cases::sphere_in_box_3d(n, nr);
    let mut linear = case.mesh.clone();
    linear.retain_tags(|dim, tag| case.projector.get(dim, tag).is_some());
    println!("| p | cells | certified (s, median of {reps}) | per cell (ms) | sampled Q1-Q3 (s) | certified min Q3 | sampled min Q3 | invalid / uncertain |");
    println!("|---|---|---|---|---|---|---|---|");
    for p in orders {
        let opts = CurveOptions { order: p, formulation: Formulation::Linear, ..Default::default() };
        let c = curve(&linear, &case.projector, &opts, &mut |_| true)?;
        let mesh = &c.mesh;
        let basis = LagrangeBasis::new(&NodeSet::new(mesh.simplex, p, mesh.spacing));
        let (mut tc, mut ts) = (Vec::new(), Vec::new());
        let mut last = None;
        for _ in 0..reps {
            let t = Instant::now();
            let b = quality::certify_cells(&basis, &mesh.coords, &mesh.cells);
            tc.push(t.elapsed().as_secs_f64());
            last = Some(b);
            let t = Instant::now();
            let cache = quality::sampling_cache(&basis);
            std::hint::black_box(quality::cell_qualities(&cache, &mesh.coords, Some(&c.straight), &mesh.cells, None));
            ts.push(t.elapsed().as_secs_f64());
        }
        let cells = mesh.n_cells();
        let bounds = last.as_ref().and_then(|b| b.bounds());
        let (cmin, bad) = bounds.map_or((f64::NAN, (0, 0)), |b| {
            let m = b.iter().map(CertifiedJacobian::q3_lower).fold(f64::INFINITY, f64::min);
            let count = |v| b.iter().filter(|c| c.verdict == v).count();
            (m, (count(Verdict::Invalid), count(Verdict::Uncertain)))
        });
        let tcm = median(tc);
        println!(
            "| {p} | {cells} | {tcm:.4} | {:.3} | {:.4} | {cmin:.4} | {:.4} | {} / {} |",
            1e3 * tcm / cells as f64,
            median(ts),
            c.report.quality.min_q3,
            bad.0,
            bad.1
        );
    }
    Ok(())
}
