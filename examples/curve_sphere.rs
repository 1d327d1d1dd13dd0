//! The README's library example: curve the built-in sphere cavity at p = 4.
//! `cargo run --release --example curve_sphere`

use hocurve::cases;
use hocurve::curve::{curve, CurveOptions};

fn main() -> hocurve::Result<()> {
    let case = cases::sphere_in_box_3d(3, 2); // or build a hocurve::mesh::LinearMesh
    let mut mesh = case.mesh.clone();
    mesh.retain_tags(|dim, tag| case.projector.get(dim, tag).is_some());
    let opts = CurveOptions { order: 4, increments: 10, ..Default::default() };
    let curved = curve(&mesh, &case.projector, &opts, &mut |_progress| true)?;
    println!("min Q3 = {}", curved.report.quality.min_q3);
    hocurve::io::write_mesh(std::path::Path::new("curved.vtu"), &curved.mesh, Some(&curved.cell_quality))?;
    Ok(())
}
