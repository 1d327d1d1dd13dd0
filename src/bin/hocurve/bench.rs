//! `hocurve bench`: time and memory of ILE curving against problem size.
//!
//! For each dimension and order, a series of built-in cases of growing size
//! (2D: [`cases::cylinder_channel_2d`] with more divisions around the
//! cylinder; 3D: [`cases::sphere_in_box_3d`] with more divisions per cube
//! face and as many radial layers) is curved, each case in a child process
//! (`hocurve bench-one`, hidden) so that its peak memory (VmHWM) is its own
//! and a crash or an out-of-memory kill becomes a failed row, not a failed
//! table. A series stops before the first case whose unknowns, counted from
//! the linear mesh's topology before it runs, exceed `--max-dofs`.
//!
//! After the table come the measured exponents: the least-squares slope of
//! ln t against ln N (N = unknowns) for the solve phase and the whole run.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;
use std::time::Instant;

use hocurve::cases::{self, Case};
use hocurve::curve::{curve, CurveOptions, Formulation, Stage};
use hocurve::mesh::Topology;
use hocurve::solver::{DirectOrdering, SolverChoice};
use hocurve::{Error, Result};

use super::{heap, write_text_atomic, Args};

/// Largest unknown count of a series by default: the full table takes about
/// ten minutes on two cores with the direct solver.
pub const DEFAULT_MAX_DOFS: usize = 210_000;
/// The same for `--quick` (about a minute).
pub const QUICK_MAX_DOFS: usize = 60_000;

/// Boundary-layer cells and stretching of the 2D series (as in `hocurve demo`).
const LAYERS_2D: usize = 8;
const STRETCHING_2D: f64 = 100.0;

/// Size parameter ladders: cells grow by about 1.5–2.5× a step in 2D
/// (divisions around the cylinder) and by (n+1)³/n³ in 3D (divisions per
/// cube-sphere face edge, as many radial layers; 72·n³ tetrahedra).
const LADDER_2D: &[usize] = &[16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024, 1536, 2048];
const LADDER_3D: &[usize] = &[1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 14, 16, 20, 24];

/// The built-in case of a series at size parameter `size`.
fn bench_case(dim: usize, size: usize) -> Result<Case> {
    match dim {
        2 => Ok(cases::cylinder_channel_2d(size, LAYERS_2D, STRETCHING_2D)),
        3 => Ok(cases::sphere_in_box_3d(size, size)),
        _ => Err(Error::InvalidInput(format!("bench: dimension must be 2 or 3, got {dim}"))),
    }
}

/// Stretchings of `hocurve bench --layers`; 1 is the isotropic mesh the others are compared with.
pub const LAYER_STRETCHINGS: [f64; 4] = [1.0, 100.0, 300.0, 1000.0];

/// Layers of the boundary-layer cases, and their growth (1 at stretching 1).
const LAYERS: usize = 23;
const GROWTH: f64 = 1.3;

/// Size of the boundary-layer cases at order `p`: 512 divisions around the
/// circle in 2D (92,160 unknowns at p = 2); in 3D the icosphere of level 2
/// at p = 2 (320 triangles, 22,080 tets, 86,670 unknowns) and of level 1
/// above (80 triangles, 5,520 tets).
fn layer_size(dim: usize, p: usize) -> usize {
    match (dim, p) {
        (2, _) => 512,
        (_, 2) => 2,
        _ => 1,
    }
}

/// The boundary-layer case at `stretching` (first-layer edge / height),
/// [`LAYERS`] layers growing by [`GROWTH`]: in 2D on the unit circle with
/// `size` divisions around, quads split into triangles; in 3D prisms on the
/// icosphere of level `size`, split into tets. Stretching 1 (with layers of
/// equal thickness) is the isotropic mesh of the same size.
fn layer_case(dim: usize, size: usize, stretching: f64) -> Result<Case> {
    let growth = if stretching == 1.0 { 1.0 } else { GROWTH };
    match dim {
        2 => Ok(cases::circle_layers_2d(size, LAYERS, stretching, growth)),
        3 => Ok(cases::sphere_layers_3d(size, LAYERS, stretching, growth)),
        _ => Err(Error::InvalidInput(format!("bench: dimension must be 2 or 3, got {dim}"))),
    }
}

/// Unknowns of the ILE system at order `p` on `case`: dim × (nodes not on the
/// boundary), since every boundary node is prescribed. Counted from the
/// linear topology: interior vertices, (p−1) nodes per interior edge,
/// (p−1)(p−2)/2 per interior face and (p−1)(p−2)(p−3)/6 per tetrahedron.
fn predicted_unknowns(case: &Case, p: usize) -> Result<usize> {
    let mesh = &case.mesh;
    let topo = Topology::new(mesh)?;
    let (e, f, c) =
        (p - 1, (p - 1) * (p.saturating_sub(2)) / 2, (p - 1) * p.saturating_sub(2) * p.saturating_sub(3) / 6);
    let boundary_vertices = topo.boundary_vertex.iter().filter(|&&b| b).count();
    let interior = if mesh.dim == 2 {
        let boundary_edges = topo.boundary_facets.len();
        (mesh.n_vertices() - boundary_vertices) + (topo.edges.len() - boundary_edges) * e + mesh.n_cells() * f
    } else {
        let mut boundary_edges = std::collections::HashSet::new();
        for &face in &topo.boundary_facets {
            let [a, b, c] = topo.faces[face];
            boundary_edges.extend([[a, b], [a, c], [b, c]]);
        }
        let boundary_faces = topo.boundary_facets.len();
        (mesh.n_vertices() - boundary_vertices)
            + (topo.edges.len() - boundary_edges.len()) * e
            + (topo.faces.len() - boundary_faces) * f
            + mesh.n_cells() * c
    };
    Ok(mesh.dim * interior)
}

/// One row of the table: what `bench-one` printed, or why it failed.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub dim: usize,
    pub order: usize,
    pub size: usize,
    pub cells: usize,
    pub nodes: usize,
    pub unknowns: usize,
    /// The boundary-layer case at this stretching ([`layer_case`]), or 0 for
    /// the series case ([`bench_case`]).
    pub stretching: f64,
    pub solver: String,
    /// Mean Krylov iterations per linear solve; `None` for a direct solver.
    pub iterations: Option<f64>,
    /// Solves the first solver did not produce (it fell back).
    pub fallbacks: usize,
    pub elevate_project: f64,
    pub assembly: f64,
    pub setup: f64,
    pub solve: f64,
    pub quality: f64,
    pub total: f64,
    /// Wall time of the child process seen by the parent (includes building
    /// the case and starting the process).
    pub wall: f64,
    pub peak_mb: f64,
    /// Peak heap of each phase of the run, in MB, in the order they ran
    /// ([`PHASES`]): the most bytes allocated at once from its start to
    /// the next phase's, the case's own mesh and projector included.
    pub heap_mb: Vec<(String, f64)>,
    pub min_q3: f64,
    /// `Some(reason)` for a failed run (then the numbers above are NaN or 0).
    pub failure: Option<String>,
}

impl Row {
    /// The machine-readable line printed by `bench-one`: `key=value` pairs
    /// separated by spaces, after the word `bench-one`.
    fn to_line(&self) -> String {
        format!(
            "bench-one dim={} p={} size={} cells={} nodes={} unknowns={} stretching={} solver={} iterations={} \
             fallbacks={} elevate_project={:e} \
             assembly={:e} setup={:e} solve={:e} quality={:e} total={:e} peak_mb={:.1} heap_mb={} min_q3={}",
            self.dim,
            self.order,
            self.size,
            self.cells,
            self.nodes,
            self.unknowns,
            self.stretching,
            self.solver,
            self.iterations.map_or("-".to_string(), |i| format!("{i:.1}")),
            self.fallbacks,
            self.elevate_project,
            self.assembly,
            self.setup,
            self.solve,
            self.quality,
            self.total,
            self.peak_mb,
            if self.heap_mb.is_empty() {
                "-".to_string()
            } else {
                self.heap_mb.iter().map(|(k, v)| format!("{k}:{v:.1}")).collect::<Vec<_>>().join(",")
            },
            self.min_q3
        )
    }

    /// Parse the line of [`Row::to_line`] (the wall time is the parent's to fill).
    fn from_line(line: &str) -> Option<Row> {
        let rest = line.trim().strip_prefix("bench-one ")?;
        let kv: Vec<(&str, &str)> = rest.split_whitespace().filter_map(|t| t.split_once('=')).collect();
        let get = |k: &str| kv.iter().find(|(n, _)| *n == k).map(|(_, v)| *v);
        let int = |k: &str| get(k)?.parse::<usize>().ok();
        let real = |k: &str| get(k)?.parse::<f64>().ok();
        Some(Row {
            dim: int("dim")?,
            order: int("p")?,
            size: int("size")?,
            cells: int("cells")?,
            nodes: int("nodes")?,
            unknowns: int("unknowns")?,
            stretching: real("stretching")?,
            solver: get("solver")?.to_string(),
            iterations: match get("iterations")? {
                "-" => None,
                v => Some(v.parse().ok()?),
            },
            fallbacks: int("fallbacks")?,
            elevate_project: real("elevate_project")?,
            assembly: real("assembly")?,
            setup: real("setup")?,
            solve: real("solve")?,
            quality: real("quality")?,
            total: real("total")?,
            wall: f64::NAN,
            peak_mb: real("peak_mb")?,
            heap_mb: match get("heap_mb")? {
                "-" => Vec::new(),
                v => v
                    .split(',')
                    .map(|kv| kv.split_once(':').and_then(|(k, m)| Some((k.to_string(), m.parse().ok()?))))
                    .collect::<Option<Vec<_>>>()?,
            },
            min_q3: real("min_q3")?,
            failure: None,
        })
    }

    fn failed(job: &Job, unknowns: usize, solver: &str, wall: f64, why: String) -> Row {
        Row {
            dim: job.dim,
            order: job.order,
            size: job.size,
            cells: 0,
            nodes: 0,
            unknowns,
            stretching: job.stretching,
            solver: solver.to_string(),
            iterations: None,
            fallbacks: 0,
            elevate_project: f64::NAN,
            assembly: f64::NAN,
            setup: f64::NAN,
            solve: f64::NAN,
            quality: f64::NAN,
            total: f64::NAN,
            wall,
            peak_mb: f64::NAN,
            heap_mb: Vec::new(),
            min_q3: f64::NAN,
            failure: Some(why),
        }
    }
}

/// The phases of a run, as `bench-one` names them: the preparation (cell
/// orientation, caps, repair) until the first progress report, then the
/// stages of [`Stage`].
pub const PHASES: [&str; 6] = ["prepare", "elevate", "project", "increments", "quality", "optimize"];

fn phase_name(stage: Stage) -> &'static str {
    match stage {
        Stage::Elevate => PHASES[1],
        Stage::Project => PHASES[2],
        Stage::Increment => PHASES[3],
        Stage::Quality => PHASES[4],
        Stage::Optimize => PHASES[5],
    }
}

/// The peak heap of each phase of one run, from the progress reports.
struct PhasePeaks {
    current: &'static str,
    peaks: Vec<(String, f64)>,
}

impl PhasePeaks {
    /// At the start of a run: its first phase begins.
    fn new() -> Self {
        heap::reset_peak();
        PhasePeaks { current: PHASES[0], peaks: Vec::new() }
    }

    /// A progress report from phase `name`: if it is a new one, the last ends.
    fn enter(&mut self, name: &'static str) {
        if name != self.current {
            self.close();
            self.current = name;
        }
    }

    fn close(&mut self) {
        let mb = heap::peak() as f64 / (1u64 << 20) as f64;
        match self.peaks.iter_mut().find(|(k, _)| k == self.current) {
            Some((_, m)) => *m = m.max(mb),
            None => self.peaks.push((self.current.to_string(), mb)),
        }
        heap::reset_peak();
    }

    /// At the end of the run: the peaks, in MB.
    fn finish(mut self) -> Vec<(String, f64)> {
        self.close();
        self.peaks
    }
}

/// Peak resident set size of this process (VmHWM), in MB; NaN where
/// /proc is not available.
fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
            let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
            Some(kb / 1024.0)
        })
        .unwrap_or(f64::NAN)
}

/// `hocurve bench-one --dim D --order P --size K [--increments N] [--solver S]
/// [--direct-ordering amd|nd|auto] [--condense on|off]`: curve one case and print one
/// [`Row::to_line`] on stdout.
pub fn cmd_bench_one(argv: &[String]) -> Result<()> {
    let args = Args::parse(
        argv,
        &["dim", "order", "size", "stretching", "increments", "solver", "direct-ordering", "condense"],
    )?;
    let dim: usize = args.number("dim", 2)?;
    let size: usize = args.number("size", LADDER_2D[0])?;
    let stretching: f64 = args.number("stretching", 0.0)?;
    let case = if stretching > 0.0 { layer_case(dim, size, stretching)? } else { bench_case(dim, size)? };
    let mut opts = CurveOptions {
        order: args.number("order", 2)?,
        formulation: Formulation::Ile,
        increments: args.number("increments", 1)?,
        // Fixed increments, as timed: adaptive stepping would turn the
        // smallest 3D case (inverted at p >= 3 whatever the steps) into a
        // failure; its min Q3 column says it is invalid.
        adaptive: Some(false),
        ..Default::default()
    };
    if let Some(s) = args.get("solver") {
        opts.solver = SolverChoice::parse(s)?;
    }
    if let Some(s) = args.get("direct-ordering") {
        opts.direct_ordering = DirectOrdering::parse(s)?;
    }
    opts.condense = args.on_off("condense")?.unwrap_or(opts.condense);
    hocurve::curve::validate_options(&opts)?;
    let mut mesh = case.mesh.clone();
    mesh.retain_tags(|d, t| case.projector.get(d, t).is_some());
    let mut phases = PhasePeaks::new();
    let c = curve(&mesh, &case.projector, &opts, &mut |p| {
        phases.enter(phase_name(p.stage));
        true
    })?;
    let heap_mb = phases.finish();
    let r = &c.report;
    let t = &r.timings;
    let iterative = r.solves.iterations.iter().any(|&i| i > 0);
    let row = Row {
        dim,
        order: r.order,
        size,
        cells: r.cells,
        nodes: r.nodes,
        unknowns: r.dofs,
        stretching,
        solver: r.solves.solver.to_string(),
        fallbacks: r.solves.fallback.iter().filter(|f| f.is_some()).count(),
        iterations: iterative
            .then(|| r.solves.iterations.iter().sum::<usize>() as f64 / r.solves.iterations.len() as f64),
        elevate_project: t.elevate + t.project,
        assembly: t.assembly,
        setup: t.setup,
        solve: t.solve,
        quality: t.quality,
        total: t.total,
        wall: f64::NAN,
        peak_mb: peak_rss_mb(),
        heap_mb,
        min_q3: r.quality.min_q3,
        failure: None,
    };
    println!("{}", row.to_line());
    Ok(())
}

/// What `hocurve bench` runs.
#[derive(Debug, Clone)]
pub struct BenchConfig {
    pub dims: Vec<usize>,
    pub orders: Vec<usize>,
    pub max_dofs: usize,
    pub increments: usize,
    pub solver: String,
    /// The boundary-layer cases at [`LAYER_STRETCHINGS`] instead of the series.
    pub layers: bool,
}

fn parse_list(flag: &str, s: &str) -> Result<Vec<usize>> {
    s.split(',')
        .map(|v| v.trim().parse().map_err(|_| Error::InvalidInput(format!("--{flag}: '{v}' is not an integer"))))
        .collect()
}

impl BenchConfig {
    fn from_args(args: &Args, quick: bool, layers: bool) -> Result<BenchConfig> {
        let orders = match (quick, layers) {
            (true, _) => "2,4",
            (false, true) => "2,3,4",
            (false, false) => "2,3,4,5,6",
        };
        let c = BenchConfig {
            dims: parse_list("dims", args.get("dims").unwrap_or("2,3"))?,
            orders: parse_list("orders", args.get("orders").unwrap_or(orders))?,
            max_dofs: args.number("max-dofs", if quick { QUICK_MAX_DOFS } else { DEFAULT_MAX_DOFS })?,
            increments: args.number("increments", 1)?,
            // The layer cases measure PCG, which `auto` would not run in 2D.
            solver: args.get("solver").unwrap_or(if layers { "iterative" } else { "auto" }).to_string(),
            layers,
        };
        if let Some(d) = c.dims.iter().find(|&&d| d != 2 && d != 3) {
            return Err(Error::InvalidInput(format!("--dims: dimension must be 2 or 3, got {d}")));
        }
        if let Some(p) = c.orders.iter().find(|&&p| !(2..=10).contains(&p)) {
            return Err(Error::InvalidInput(format!("--orders: order must be in 2..=10, got {p}")));
        }
        if c.increments == 0 {
            return Err(Error::InvalidInput("--increments must be at least 1".into()));
        }
        SolverChoice::parse(&c.solver)?;
        Ok(c)
    }
}

/// Run one case in a child process (this executable, `bench-one`).
fn run_child(cfg: &BenchConfig, job: &Job, unknowns: usize) -> Row {
    let start = Instant::now();
    let exe = match std::env::current_exe() {
        Ok(e) => e,
        Err(e) => return Row::failed(job, unknowns, &cfg.solver, 0.0, format!("current_exe: {e}")),
    };
    let (dim, order, size) = (job.dim.to_string(), job.order.to_string(), job.size.to_string());
    let out = Command::new(exe)
        .args(["bench-one", "--dim", &dim, "--order", &order, "--size", &size])
        .args(["--stretching", &job.stretching.to_string()])
        .args(["--increments", &cfg.increments.to_string(), "--solver", &cfg.solver])
        .output();
    let wall = start.elapsed().as_secs_f64();
    let out = match out {
        Ok(o) => o,
        Err(e) => return Row::failed(job, unknowns, &cfg.solver, wall, format!("spawn: {e}")),
    };
    let stdout = String::from_utf8_lossy(&out.stdout);
    let row = stdout.lines().find_map(Row::from_line);
    match (out.status.success(), row) {
        (true, Some(mut r)) => {
            r.wall = wall;
            r
        }
        (ok, _) => {
            let stderr = String::from_utf8_lossy(&out.stderr);
            let last = stderr.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("").trim().to_string();
            let why = if ok {
                "no result line".to_string()
            } else {
                use std::os::unix::process::ExitStatusExt;
                match out.status.signal() {
                    Some(9) => "killed (signal 9, out of memory?)".to_string(),
                    Some(s) => format!("signal {s}"),
                    None => format!("exit {}: {last}", out.status.code().unwrap_or(-1)),
                }
            };
            Row::failed(job, unknowns, &cfg.solver, wall, why)
        }
    }
}

/// One case of a bench: the series case of `size`, or the boundary-layer
/// case at `stretching` (> 0).
pub struct Job {
    pub dim: usize,
    pub order: usize,
    pub size: usize,
    pub stretching: f64,
}

/// Run every series; `on_row` sees each row as it completes.
pub fn run(cfg: &BenchConfig, mut on_row: impl FnMut(&Row)) -> Result<Vec<Row>> {
    let mut rows = Vec::new();
    if cfg.layers {
        for &dim in &cfg.dims {
            for &order in &cfg.orders {
                let size = layer_size(dim, order);
                for stretching in LAYER_STRETCHINGS {
                    let unknowns = predicted_unknowns(&layer_case(dim, size, stretching)?, order)?;
                    let row = run_child(cfg, &Job { dim, order, size, stretching }, unknowns);
                    on_row(&row);
                    rows.push(row);
                }
            }
        }
        return Ok(rows);
    }
    for &dim in &cfg.dims {
        for &p in &cfg.orders {
            let ladder = if dim == 2 { LADDER_2D } else { LADDER_3D };
            for &size in ladder {
                let unknowns = predicted_unknowns(&bench_case(dim, size)?, p)?;
                if unknowns > cfg.max_dofs {
                    break;
                }
                let row = run_child(cfg, &Job { dim, order: p, size, stretching: 0.0 }, unknowns);
                on_row(&row);
                let failed = row.failure.is_some();
                rows.push(row);
                if failed {
                    break;
                }
            }
        }
    }
    Ok(rows)
}

/// Least-squares slope of ln y against ln x over the points with x, y > 0
/// (finite); `None` with fewer than two distinct x.
pub fn loglog_slope(points: &[(f64, f64)]) -> Option<f64> {
    let pts: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| x.is_finite() && y.is_finite() && *x > 0.0 && *y > 0.0)
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    let n = pts.len() as f64;
    if pts.len() < 2 {
        return None;
    }
    let (mx, my) = (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 1e-12).then(|| sxy / sxx)
}

/// Smallest run time that enters an exponent fit: below it, process start-up
/// and timer resolution dominate.
pub const FIT_MIN_SECONDS: f64 = 0.01;

/// Measured exponents of one (dim, p) series.
#[derive(Debug, Clone, PartialEq)]
pub struct Exponents {
    pub dim: usize,
    pub order: usize,
    /// Runs in the fit of the total time.
    pub points: usize,
    /// Slopes over every run with t >= [`FIT_MIN_SECONDS`].
    pub solve: Option<f64>,
    pub total: Option<f64>,
    /// Slopes between the two largest such runs (the local exponent).
    pub solve_last: Option<f64>,
    pub total_last: Option<f64>,
}

/// The exponents of each (dim, p) series in `rows`, in order of appearance.
pub fn exponents(rows: &[Row]) -> Vec<Exponents> {
    let mut keys: Vec<(usize, usize)> = rows.iter().map(|r| (r.dim, r.order)).collect();
    keys.dedup();
    keys.into_iter()
        .map(|(dim, order)| {
            let ok: Vec<&Row> =
                rows.iter().filter(|r| r.dim == dim && r.order == order && r.failure.is_none()).collect();
            let points = |t: fn(&Row) -> f64| -> Vec<(f64, f64)> {
                ok.iter().filter(|r| t(r) >= FIT_MIN_SECONDS).map(|r| (r.unknowns as f64, t(r))).collect()
            };
            let last2 = |p: &[(f64, f64)]| loglog_slope(&p[p.len().saturating_sub(2)..]);
            let (solve, total) = (points(|r| r.solve), points(|r| r.total));
            Exponents {
                dim,
                order,
                points: total.len(),
                solve: loglog_slope(&solve),
                total: loglog_slope(&total),
                solve_last: last2(&solve),
                total_last: last2(&total),
            }
        })
        .collect()
}

const HEADER: [&str; 18] = [
    "dim",
    "p",
    "size",
    "cells",
    "nodes",
    "unknowns",
    "solver",
    "iters",
    "elev+proj",
    "assembly",
    "setup",
    "solve",
    "quality",
    "total",
    "wall",
    "peak_MB",
    "min_Q3",
    "status",
];
const WIDTHS: [usize; 18] = [3, 2, 5, 8, 9, 9, 7, 6, 9, 9, 8, 9, 8, 9, 9, 8, 7, 0];

fn secs(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.3}")
    } else {
        "-".into()
    }
}

fn cells_of(r: &Row) -> [String; 18] {
    let int = |v: usize| if r.failure.is_some() && v == 0 { "-".to_string() } else { v.to_string() };
    [
        r.dim.to_string(),
        r.order.to_string(),
        r.size.to_string(),
        int(r.cells),
        int(r.nodes),
        r.unknowns.to_string(),
        r.solver.clone(),
        r.iterations.map_or("-".into(), |i| format!("{i:.1}")),
        secs(r.elevate_project),
        secs(r.assembly),
        secs(r.setup),
        secs(r.solve),
        secs(r.quality),
        secs(r.total),
        secs(r.wall),
        if r.peak_mb.is_finite() { format!("{:.0}", r.peak_mb) } else { "-".into() },
        if r.min_q3.is_finite() { format!("{:.3}", r.min_q3) } else { "-".into() },
        r.failure.as_ref().map_or("ok".to_string(), |f| format!("FAILED: {f}")),
    ]
}

/// The table header line.
pub fn header_line() -> String {
    HEADER.iter().zip(WIDTHS).map(|(h, w)| format!("{h:>w$}")).collect::<Vec<_>>().join(" ")
}

/// One table line.
pub fn row_line(r: &Row) -> String {
    cells_of(r).iter().zip(WIDTHS).map(|(c, w)| format!("{c:>w$}")).collect::<Vec<_>>().join(" ")
}

/// The exponent lines that follow the table.
pub fn exponent_lines(rows: &[Row]) -> String {
    let mut s = format!(
        "\nmeasured exponents: least-squares slope of ln t vs ln N (N = unknowns) over the runs with \
         t >= {FIT_MIN_SECONDS} s, and between the two largest of them (last2)\n\
         {:>3} {:>2} {:>6} {:>7} {:>7} {:>12} {:>12}\n",
        "dim", "p", "points", "solve", "total", "solve_last2", "total_last2"
    );
    let e = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{v:.2}"));
    for x in exponents(rows) {
        let _ = writeln!(
            s,
            "{:>3} {:>2} {:>6} {:>7} {:>7} {:>12} {:>12}",
            x.dim,
            x.order,
            x.points,
            e(x.solve),
            e(x.total),
            e(x.solve_last),
            e(x.total_last)
        );
    }
    s
}

/// The lines that follow a `--layers` table: per dimension and order, each
/// stretching's iterations and time per unknown against the isotropic mesh's.
pub fn layer_lines(rows: &[Row]) -> String {
    let mut s = format!(
        "\nboundary layers against the isotropic mesh (stretching 1) of the same size and order\n\
         {:>3} {:>2} {:>10} {:>9} {:>7} {:>9} {:>9} {:>10} {:>9} {:>9}\n",
        "dim", "p", "stretching", "unknowns", "iters", "fallbacks", "total_s", "us/unknown", "iters/iso", "time/iso"
    );
    let per_unknown = |r: &Row| 1e6 * r.total / r.unknowns.max(1) as f64;
    for r in rows {
        let iso = rows.iter().find(|i| i.dim == r.dim && i.order == r.order && i.stretching == 1.0);
        let ratio = |f: &dyn Fn(&Row) -> Option<f64>| match (iso.and_then(f), f(r)) {
            (Some(a), Some(b)) if a > 0.0 && r.failure.is_none() => format!("{:.2}", b / a),
            _ => "-".into(),
        };
        let _ = writeln!(
            s,
            "{:>3} {:>2} {:>10} {:>9} {:>7} {:>9} {:>9} {:>10} {:>9} {:>9}{}",
            r.dim,
            r.order,
            r.stretching,
            r.unknowns,
            r.iterations.map_or("-".into(), |i| format!("{i:.1}")),
            r.fallbacks,
            secs(r.total),
            if r.total.is_finite() { format!("{:.2}", per_unknown(r)) } else { "-".into() },
            ratio(&|x: &Row| x.iterations),
            ratio(&|x: &Row| x.total.is_finite().then(|| per_unknown(x))),
            r.failure.as_ref().map_or(String::new(), |f| format!("  FAILED: {f}")),
        );
    }
    s
}

/// A row's peak heap in phase `name`, in MB (NaN if it did not run).
fn heap_of(r: &Row, name: &str) -> f64 {
    r.heap_mb.iter().find(|(k, _)| k == name).map_or(f64::NAN, |(_, m)| *m)
}

/// The memory lines that follow the exponents: the peak heap of each phase,
/// and the largest per unknown.
pub fn memory_lines(rows: &[Row]) -> String {
    let mut s = format!(
        "
peak heap per phase (MB; the case's mesh included), and the largest of them per unknown
         {:>3} {:>2} {:>9}",
        "dim", "p", "unknowns"
    );
    for name in PHASES {
        let _ = write!(s, " {name:>10}");
    }
    let _ = writeln!(s, " {:>10}", "KB/unknown");
    for r in rows.iter().filter(|r| r.failure.is_none()) {
        let _ = write!(s, "{:>3} {:>2} {:>9}", r.dim, r.order, r.unknowns);
        for name in PHASES {
            let m = heap_of(r, name);
            let _ = write!(s, " {:>10}", if m.is_finite() { format!("{m:.1}") } else { "-".into() });
        }
        let top = r.heap_mb.iter().map(|(_, m)| *m).fold(f64::NAN, f64::max);
        let _ = writeln!(s, " {:>10.2}", top * 1024.0 / r.unknowns.max(1) as f64);
    }
    s
}

/// The table as CSV (one header line, one line per row; seconds as given).
pub fn csv(rows: &[Row]) -> String {
    let mut s = "dim,p,size,cells,nodes,unknowns,solver,iterations,elevate_project_s,assembly_s,setup_s,solve_s,\
                 quality_s,total_s,wall_s,peak_mb,min_q3,status"
        .to_string();
    for name in PHASES {
        let _ = write!(s, ",heap_{name}_mb");
    }
    s.push('\n');
    let f = |x: f64| if x.is_finite() { format!("{x}") } else { String::new() };
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.dim,
            r.order,
            r.size,
            r.cells,
            r.nodes,
            r.unknowns,
            r.solver,
            r.iterations.map_or(String::new(), |i| format!("{i}")),
            f(r.elevate_project),
            f(r.assembly),
            f(r.setup),
            f(r.solve),
            f(r.quality),
            f(r.total),
            f(r.wall),
            f(r.peak_mb),
            f(r.min_q3),
            r.failure.as_ref().map_or("ok".to_string(), |w| format!("\"failed: {}\"", w.replace('"', "'")))
        );
        s.pop();
        for name in PHASES {
            let _ = write!(s, ",{}", f(heap_of(r, name)));
        }
        s.push('\n');
    }
    s
}

/// `hocurve bench [--quick] [--dims 2,3] [--orders 2,3,4,5,6] [--max-dofs N]
/// [--increments N] [--solver S] [--csv FILE]`.
pub fn cmd_bench(argv: &[String]) -> Result<()> {
    let quick = argv.iter().any(|a| a == "--quick");
    let layers = argv.iter().any(|a| a == "--layers");
    let rest: Vec<String> = argv.iter().filter(|a| *a != "--quick" && *a != "--layers").cloned().collect();
    let args = Args::parse(&rest, &["dims", "orders", "max-dofs", "increments", "solver", "csv"])?;
    if let Some(p) = args.positional.first() {
        return Err(Error::InvalidInput(format!("bench takes no positional argument, got '{p}'")));
    }
    let cfg = BenchConfig::from_args(&args, quick, layers)?;
    let csv_path = args.get("csv").map(Path::new);
    if let Some(p) = csv_path {
        let dir = p.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        if !dir.is_dir() {
            return Err(Error::Io(format!("cannot write {}: directory {} does not exist", p.display(), dir.display())));
        }
    }
    eprintln!(
        "bench: ILE, {} increment(s), solver {}, dims {:?}, orders {:?}, up to {} unknowns; seconds per phase, \
         each case in its own process",
        cfg.increments, cfg.solver, cfg.dims, cfg.orders, cfg.max_dofs
    );
    let start = Instant::now();
    println!("{}", header_line());
    let rows = run(&cfg, |r| {
        println!("{}", row_line(r));
        let _ = std::io::Write::flush(&mut std::io::stdout());
    })?;
    if cfg.layers {
        print!("{}", layer_lines(&rows));
    } else {
        print!("{}", exponent_lines(&rows));
    }
    print!("{}", memory_lines(&rows));
    eprintln!("bench: {} runs in {:.1} s", rows.len(), start.elapsed().as_secs_f64());
    if let Some(p) = csv_path {
        write_text_atomic(p, &csv(&rows))?;
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loglog_slope_recovers_a_power_law() {
        let pts: Vec<(f64, f64)> = [1e3, 4e3, 1.6e4].iter().map(|&n: &f64| (n, 3e-6 * n.powf(1.5))).collect();
        assert!((loglog_slope(&pts).unwrap() - 1.5).abs() < 1e-12);
        assert_eq!(loglog_slope(&pts[..1]), None);
    }

    #[test]
    fn row_line_round_trips() {
        let r = Row {
            dim: 3,
            order: 4,
            size: 2,
            cells: 576,
            nodes: 9000,
            unknowns: 20000,
            stretching: 300.0,
            solver: "direct".into(),
            iterations: None,
            fallbacks: 1,
            elevate_project: 0.01,
            assembly: 0.5,
            setup: 0.02,
            solve: 1.25,
            quality: 0.1,
            total: 1.9,
            wall: f64::NAN,
            peak_mb: 123.4,
            heap_mb: vec![("prepare".into(), 1.5), ("increments".into(), 99.0)],
            min_q3: 0.71,
            failure: None,
        };
        let back = Row::from_line(&r.to_line()).unwrap();
        assert_eq!(back.to_line(), r.to_line());
    }

    #[test]
    fn predicted_unknowns_match_the_curved_report() {
        for (dim, size, p) in [(2, 16, 3), (3, 1, 4), (3, 2, 2)] {
            let case = bench_case(dim, size).unwrap();
            // The coarsest 3D case cannot come out valid at p = 4: adaptive
            // stepping would fail at its limit, and only the count matters here.
            let opts = CurveOptions { order: p, adaptive: Some(false), ..Default::default() };
            let mut mesh = case.mesh.clone();
            mesh.retain_tags(|d, t| case.projector.get(d, t).is_some());
            let c = curve(&mesh, &case.projector, &opts, &mut |_| true).unwrap();
            assert_eq!(predicted_unknowns(&case, p).unwrap(), c.report.dofs, "dim {dim} size {size} p {p}");
        }
    }
}
