//! The JSON report of a run, as the command line writes it and the Python
//! package returns it: text only, no file is touched here.

use std::path::Path;

use crate::curve::CurveReport;
use crate::quality::MeshQuality;
use crate::reference::NodeSpacing;

pub fn json_escape(s: &str) -> String {
    let mut o = String::new();
    for c in s.chars() {
        match c {
            '"' => o.push_str("\\\""),
            '\\' => o.push_str("\\\\"),
            c if (c as u32) < 0x20 => o.push_str(&format!("\\u{:04x}", c as u32)),
            c => o.push(c),
        }
    }
    o
}

fn num(x: f64) -> String {
    if x.is_finite() {
        format!("{x}")
    } else {
        "null".into()
    }
}

pub fn quality_json(q: &MeshQuality) -> String {
    format!(
        "  \"min_q1\": {},\n  \"min_q2\": {},\n  \"min_q3\": {},\n  \"min_q4\": {},\n  \"min_q5\": {},\n  \"mean_q3\": {},\n  \"invalid_elements\": {},\n  \
         \"worst_cell\": {},\n  \"q3_histogram\": {:?},\n  \"certified_min_q3\": {},\n  \"certified_invalid_elements\": {},\n  \
         \"uncertain_elements\": {}",
        num(q.min_q1),
        num(q.min_q2),
        num(q.min_q3),
        num(q.min_q4),
        num(q.min_q5),
        num(q.mean_q3),
        q.n_invalid,
        q.worst_cell,
        q.histogram,
        num(q.certified_min_q3),
        q.n_certified_invalid,
        q.n_uncertain
    )
}

fn repair_json(r: &crate::mesh::RepairSummary) -> String {
    format!(
        "{{\"bad_cells\": {}, \"surface_cells\": {}, \"bulge_cells\": {}, \"flips_23\": {}, \"flips_32\": {}, \
         \"edge_removals\": {}, \"flips_22\": {}, \"surface_caps\": {}, \"cells_removed\": {}, \"cells_added\": {}, \"bad_cells_left\": {}, \"edge_splits\": {}, \"surface_flips\": {}}}",
        r.bad_cells,
        r.surface_cells,
        r.bulge_cells,
        r.flips_23,
        r.flips_32,
        r.edge_removals,
        r.flips_22,
        r.surface_caps,
        r.cells_removed,
        r.cells_added,
        r.bad_cells_left,
        r.edge_splits,
        r.surface_flips
    )
}

pub fn curve_report_json(r: &CurveReport, spacing: NodeSpacing, output: Option<&Path>) -> String {
    let t = &r.timings;
    format!(
        "{{\n  \"order\": {},\n  \"formulation\": \"{}\",\n  \"material\": \"{}\",\n  \"young\": {},\n  \
         \"poisson\": {},\n  \"increments\": {},\n  \"adaptive\": {},\n  \"max_splits\": {},\n  \
         \"increments_taken\": {},\n  \"load_fractions\": {:?},\n  \"step_backs\": [{}],\n  \"spacing\": \"{}\",\n  \"nodes\": {},\n  \"dofs\": {},\n  \"system_dofs\": {},\n  \
         \"cells\": {},\n  \"removed_caps\": {},\n  \"caps_kept_after\": {},\n  \"caps_kept_failed\": {},\n  \"repair\": {},\n  \"projected_nodes\": {},\n  \"max_projection_distance\": {},\n  \"edges_along_curves\": {},\n{},\n  \
         \"newton_history\": {:?},\n  \"linear_solver\": \"{}\",\n  \"solver_iterations\": {:?},\n  \
         \"solver_per_solve\": [{}],\n  \"solves_by_products\": {},\n  \"solves_assembled_after_products\": {},\n  \"fallbacks\": {},\n  \"fallback_per_solve\": [{}],\n  \
         \"seconds\": {{\"total\": {}, \"elevate\": {}, \"project\": {}, \"assembly\": {}, \"setup\": {}, \"solve\": {}, \"quality\": {}, \"check\": {}, \"optimize\": {}}},\n  \
         \"elastic_stop\": {},\n  \"optimization\": {},\n  \"output\": {}\n}}",
        r.order,
        r.formulation.name(),
        r.material.name(),
        num(r.young),
        num(r.poisson),
        r.increments,
        r.adaptive,
        r.max_splits,
        r.increments_taken(),
        r.load_fractions,
        r.step_backs
            .iter()
            .map(|b| format!(
                "{{\"load\": {}, \"step\": {}, \"reason\": \"{}\", \"cell\": {}}}",
                num(b.load),
                num(b.step),
                b.reason.name(),
                b.cell.map_or("null".into(), |c| c.to_string())
            ))
            .collect::<Vec<_>>()
            .join(", "),
        if spacing == NodeSpacing::Optimal { "optimal" } else { "equispaced" },
        r.nodes,
        r.dofs,
        r.system_dofs,
        r.cells,
        r.removed_caps,
        r.caps_kept_after.as_ref().map_or("null".into(), |m| format!("\"{}\"", json_escape(m))),
        r.caps_kept_failed.as_ref().map_or("null".into(), |m| format!("\"{}\"", json_escape(m))),
        repair_json(&r.repair),
        r.projected_nodes,
        num(r.max_projection_distance),
        r.edges_along_curves,
        quality_json(&r.quality),
        r.newton_history,
        r.solves.solver,
        r.solves.iterations,
        r.solves.solved_by.iter().map(|s| format!("\"{}\"", s.name())).collect::<Vec<_>>().join(", "),
        r.solves.by_products,
        r.solves.assembled_after_products,
        r.solves.fallbacks(),
        r.solves.fallback
            .iter()
            .map(|f| f.map_or("null".into(), |f| format!("\"{}\"", f.name())))
            .collect::<Vec<_>>()
            .join(", "),
        num(t.total),
        num(t.elevate),
        num(t.project),
        num(t.assembly),
        num(t.setup),
        num(t.solve),
        num(t.quality),
        num(t.check),
        num(t.optimize),
        r.elastic_stop.as_ref().map_or("null".into(), |s| format!(
            "{{\"load\": {}, \"reason\": \"{}\", \"cell\": {}, \"detail\": \"{}\", \"restarted\": {}}}",
            num(s.load),
            s.reason.name(),
            s.cell.map_or("null".into(), |c| c.to_string()),
            json_escape(&s.detail),
            s.restarted
        )),
        optimization_json(&r.optimization),
        output.map(|p| format!("\"{}\"", json_escape(&p.display().to_string()))).unwrap_or("null".into())
    )
}

fn optimization_json(o: &crate::curve::OptimizeReport) -> String {
    format!(
        "{{\"ran\": {}, \"target_cells\": {}, \"cells_touched\": {}, \"nodes_moved\": {}, \"patches\": {}, \
         \"rounds\": {}, \"cells_split\": {}, \"invalid_before\": {}, \"invalid_after\": {}, \"min_q3_before\": {}, \
         \"min_q3_after\": {}, \"seconds\": {}}}",
        o.ran,
        o.target_cells,
        o.cells_touched,
        o.nodes_moved,
        o.patches,
        o.rounds,
        o.cells_split,
        o.invalid_before,
        o.invalid_after,
        num(o.min_q3_before),
        num(o.min_q3_after),
        num(o.seconds)
    )
}
