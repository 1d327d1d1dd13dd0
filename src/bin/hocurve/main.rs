//! `hocurve`: curve linear gmsh meshes, run the built-in demo, measure quality.
//!
//! ```text
//! hocurve demo [--order P] [--output-dir DIR]
//! hocurve curve IN.msh --order P --geometry TAG=SHAPE ... [--formulation F] [--material M]
//!               [--young E] [--poisson NU] [--increments N] [--spacing optimal|equispaced] [--solver S]
//!               [--adaptive on|off] [--max-splits K] --output OUT.msh|OUT.vtu [--report R.json]
//! hocurve quality MESH.msh [--report R.json]
//! hocurve study [--quick] [--output-dir DIR]
//! hocurve bench [--quick] [--layers] [--dims 2,3] [--orders 2,3,4,5,6] [--max-dofs N] [--increments N]
//!               [--solver S] [--csv FILE]
//! ```
//! `bench` (module [`bench`]) re-runs this executable as the hidden
//! `hocurve bench-one --dim D --order P --size K ...` for each case.
//! Arguments are parsed by hand: the grammar is small and a parser crate
//! would double the build time of the binary for little gain.

mod bench;
mod heap;
#[cfg(feature = "mpi")]
mod mpi_run;
mod study;

/// Counts the heap in use, for `hocurve bench`'s memory per phase.
#[global_allocator]
static ALLOCATOR: heap::Counting = heap::Counting;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use hocurve::cases;
use hocurve::curve::{curve, CurveOptions, CurvedMesh, Formulation, Parallel, Progress, Stage};
use hocurve::geometry::shapes::{Shape, ShapeProjector};
use hocurve::io::{self, report};
use hocurve::material::MaterialModel;
use hocurve::mesh::LinearMesh;
use hocurve::quality;
use hocurve::reference::{ordering, LagrangeBasis, NodeSet, NodeSpacing};
use hocurve::solver::SolverChoice;
use hocurve::{Error, Result};

const USAGE: &str = "\
hocurve — valid high-order curved meshes by a solid-mechanics analogy

USAGE:
  hocurve demo [--order P] [--output-dir DIR]
      Curve two built-in cases (a 2D cylinder in a channel with a stretched
      boundary layer, and a 3D spherical cavity in a box) and write
      DIR/demo-2d.vtu, DIR/demo-3d.vtu and DIR/demo-report.json.

  hocurve curve IN.msh --order P --geometry TAG=SHAPE [--geometry TAG=SHAPE ...]
                --output OUT.msh|OUT.vtu [--report R.json]
                [--formulation linear|ile] [--material linear]
                [--young E] [--poisson NU] [--increments N]
                [--spacing optimal|equispaced] [--solver auto|direct|iterative]
                [--caps remove|keep] [--retry on|off] [--repair on|off]
                [--adaptive on|off] [--max-splits K] [--condense on|off] [--optimize on|off]
                [--tangent-first on|off]
                [--partitioned on|off] (hocurve-mpi: gmsh's partitioned format, a part per process)
      Curve a linear gmsh (.msh 4.1) mesh. TAG is the elementary entity tag of
      the boundary facets (or 3D feature curves) that lie on SHAPE:
        sphere:cx,cy,cz,r        circle:cx,cy,r (2D)     circle3:cx,cy,cz,nx,ny,nz,r
        cylinder:px,py,pz,ax,ay,az,r      torus:cx,cy,cz,R,r | torus:cx,cy,cz,ax,ay,az,R,r
        plane:px,py,pz,nx,ny,nz  line:px,py,pz,dx,dy,dz  naca4:DDDD,chord,x0,y0
      Boundary facets whose tag has no shape stay straight. 3D boundary caps
      (tets with two faces on one smooth surface, which cannot stay valid) are
      removed unless --caps keep; the report says how many. If the run then
      ends with an invalid cell, it is made again with the caps kept (unless
      --retry off), and the report's caps_kept_after says why. The repair (on
      unless --repair off) then flips away the cells that cannot stay valid
      with their vertices fixed: all vertices on one surface that bulges into
      the domain, or a boundary facet bulging past half the height of the
      opposite vertex, itself on the boundary (measured by projecting a few
      points of each facet), and splits the interior edges that let a smooth
      boundary squeeze a cell flat at a vertex;
      the report's repair section says what it found and did.
      Adaptive load stepping (default on, off for --formulation linear): an
      increment that inverts a cell (certified det J bounds) or whose Newton
      iteration fails is undone and halved, at most K times (--max-splits,
      default 6, at most 30); the run fails only at that limit. The increments
      taken and the step backs are printed and written to the report.
      The cell-interior nodes (p >= 4 in 3D, p >= 3 in 2D) are eliminated
      cell by cell before each solve unless --condense off (same mesh; the
      report's system_dofs counts the unknowns actually solved for).
      A linear solve that falls back (PCG restarted with a safe
      preconditioner, the direct solver after PCG, LU after Cholesky) is
      printed with its reason and listed in the report (solver_per_solve,
      fallback_per_solve, fallbacks).
      Then the optimisation stage (unless --optimize off) moves the nodes
      around every cell left invalid or with Q3 below 0.2 to untangle and
      improve it; with it on, an increment that adaptive stepping cannot
      keep valid does not stop the run: the rest of the load is applied in
      one solve and the optimisation has to make the mesh valid. The report
      says where the elastic stage stopped and what the optimisation did.
      --tangent-first on (for a slow projector; default off): the sliding
      boundary nodes move in their tangent planes and are projected after
      each pass first, and at every step only where that is not enough.

  hocurve quality MESH.msh [--report R.json]
      Measure Q1, Q2, Q3 of any high-order gmsh mesh.

  hocurve study [--quick] [--output-dir DIR]
      Sweep Poisson's ratio, p and ILE/CIL/NONLINEAR on built-in 2D cases; print
      a min-Q3 table, write DIR/study.csv and DIR/study-<case>-p<P>.svg.

  hocurve bench [--quick] [--layers] [--dims 2,3] [--orders 2,3,4,5,6] [--max-dofs N]
                [--increments N] [--solver auto|direct|iterative] [--csv FILE]
      Time ILE on built-in 2D and 3D cases of growing size at each order, each
      case in its own process: print one row per case (cells, nodes, unknowns,
      solver, mean iterations per solve, seconds of elevate+project, assembly,
      setup, solve, quality, total, peak memory in MB, min Q3), then the
      measured exponents of solve and total time against unknowns, and the
      peak heap of each phase. A series stops before its unknowns pass
      --max-dofs (default 210000, about ten minutes on two cores; --quick:
      orders 2,4 up to 60000, under a minute). --layers: boundary layers
      instead (23 layers on a circle, prisms on a sphere split into tets) at
      stretching 1, 100, 300 and 1000, orders 2,3,4, PCG by default; the
      iterations and time per unknown against the isotropic mesh.
";

pub fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    // The same source builds `hocurve-mpi`, the command line of a run
    // spread over MPI processes.
    #[cfg(feature = "mpi")]
    if env!("CARGO_BIN_NAME") == "hocurve-mpi" {
        return mpi_run::main(&args);
    }
    let result = match args.first().map(String::as_str) {
        Some("demo") => cmd_demo(&args[1..]),
        Some("curve") => cmd_curve(&args[1..], Parallel::Serial, None),
        Some("quality") => cmd_quality(&args[1..]),
        Some("study") => cmd_study(&args[1..]),
        Some("bench") => bench::cmd_bench(&args[1..]),
        Some("bench-one") => bench::cmd_bench_one(&args[1..]),
        Some("-h") | Some("--help") | Some("help") | None => {
            print!("{USAGE}");
            return ExitCode::SUCCESS;
        }
        Some("--version") => {
            println!("hocurve {}", env!("CARGO_PKG_VERSION"));
            return ExitCode::SUCCESS;
        }
        Some(other) => Err(Error::InvalidInput(format!("unknown command '{other}'; see hocurve --help"))),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hocurve: error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Parsed `--flag value` pairs plus positionals.
struct Args {
    positional: Vec<String>,
    flags: Vec<(String, String)>,
}

impl Args {
    fn parse(args: &[String], known: &[&str]) -> Result<Args> {
        let mut positional = Vec::new();
        let mut flags = Vec::new();
        let mut it = args.iter();
        while let Some(a) = it.next() {
            if let Some(name) = a.strip_prefix("--") {
                if !known.contains(&name) {
                    return Err(Error::InvalidInput(format!("unknown option --{name}")));
                }
                let v = it.next().ok_or_else(|| Error::InvalidInput(format!("option --{name} needs a value")))?;
                flags.push((name.to_string(), v.clone()));
            } else {
                positional.push(a.clone());
            }
        }
        Ok(Args { positional, flags })
    }
    fn get(&self, name: &str) -> Option<&str> {
        self.flags.iter().rev().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }
    fn all<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a str> + 'a {
        self.flags.iter().filter(move |(n, _)| n == name).map(|(_, v)| v.as_str())
    }
    /// `--name on|off`: None when absent.
    fn on_off(&self, name: &str) -> Result<Option<bool>> {
        match self.get(name) {
            None => Ok(None),
            Some("on") => Ok(Some(true)),
            Some("off") => Ok(Some(false)),
            Some(a) => Err(Error::InvalidInput(format!("unknown --{name} '{a}' (on or off)"))),
        }
    }
    fn number<T: std::str::FromStr>(&self, name: &str, default: T) -> Result<T> {
        match self.get(name) {
            None => Ok(default),
            Some(v) => v.parse().map_err(|_| Error::InvalidInput(format!("--{name}: '{v}' is not a valid number"))),
        }
    }
}

fn options_from(args: &Args, default_order: usize) -> Result<CurveOptions> {
    let mut o = CurveOptions { order: args.number("order", default_order)?, ..Default::default() };
    if let Some(f) = args.get("formulation") {
        o.formulation = Formulation::parse(f)?;
    }
    // Default material: linear for LINEAR/ILE, neo-Hookean for the formulations that need a hyperelastic one.
    o.material = match args.get("material") {
        Some(m) => MaterialModel::parse(m)?,
        None if matches!(o.formulation, Formulation::Iil | Formulation::Cil | Formulation::Nonlinear) => {
            MaterialModel::NeoHookean
        }
        None => MaterialModel::LinearElastic,
    };
    o.tolerance = args.number("tolerance", o.tolerance)?;
    o.max_iterations = args.number("max-iterations", o.max_iterations)?;
    o.young = args.number("young", o.young)?;
    o.poisson = args.number("poisson", o.poisson)?;
    o.increments = args.number("increments", o.increments)?;
    o.adaptive = args.on_off("adaptive")?;
    o.condense = args.on_off("condense")?.unwrap_or(o.condense);
    o.optimize.enabled = args.on_off("optimize")?.unwrap_or(o.optimize.enabled);
    o.optimize.tangent_first = args.on_off("tangent-first")?.unwrap_or(o.optimize.tangent_first);
    o.max_splits = args.number("max-splits", o.max_splits)?;
    o.remove_caps = match args.get("caps") {
        None | Some("remove") => true,
        Some("keep") => false,
        Some(c) => return Err(Error::InvalidInput(format!("unknown --caps '{c}' (remove or keep)"))),
    };
    o.retry_keep_caps = args.on_off("retry")?.unwrap_or(o.retry_keep_caps);
    o.repair = args.on_off("repair")?.unwrap_or(o.repair);
    if let Some(s) = args.get("solver") {
        o.solver = SolverChoice::parse(s)?;
    }
    o.spacing = match args.get("spacing") {
        None | Some("optimal") => NodeSpacing::Optimal,
        Some("equispaced") => NodeSpacing::Equispaced,
        Some(s) => return Err(Error::InvalidInput(format!("unknown spacing '{s}' (optimal or equispaced)"))),
    };
    hocurve::curve::validate_options(&o)?;
    Ok(o)
}

/// Progress on stderr, one line per stage and increment.
fn progress_printer(label: String) -> impl FnMut(&Progress) -> bool {
    move |p: &Progress| {
        let msg = match p.stage {
            Stage::Elevate => "elevating and numbering".to_string(),
            Stage::Project => "projecting boundary nodes".to_string(),
            Stage::Increment => format!("increment {}/{}", p.step + 1, p.total),
            Stage::Quality => "measuring quality".to_string(),
            Stage::Optimize => "optimising".to_string(),
        };
        eprintln!("[{label}] {msg}");
        true
    }
}

fn run_case(label: &str, mesh: &LinearMesh, projector: &ShapeProjector, opts: &CurveOptions) -> Result<CurvedMesh> {
    let mut progress = progress_printer(label.to_string());
    let c = curve(mesh, projector, opts, &mut progress)?;
    let r = &c.report;
    eprintln!(
        "[{label}] p={} nodes={} dofs={} min Q3={:.4} mean Q3={:.4} invalid={} ({:.2} s)",
        r.order, r.nodes, r.dofs, r.quality.min_q3, r.quality.mean_q3, r.quality.n_invalid, r.timings.total
    );
    if let Some(first) = &r.caps_kept_after {
        eprintln!("[{label}] made again with the caps kept, after: {first}");
    }
    if let Some(kept) = &r.caps_kept_failed {
        eprintln!(
            "[{label}] made a third time with every optimisation round, after a run with the caps kept failed: {kept}"
        );
    }
    eprintln!("[{label}] {}", increments_line(r));
    if r.solves.fallbacks() > 0 {
        eprintln!("[{label}] {}", fallbacks_line(r));
    }
    if r.quality.n_invalid > 0 {
        eprintln!(
            "[{label}] WARNING: {} invalid element(s) (worst cell {}); try more --increments or another --poisson",
            r.quality.n_invalid, r.quality.worst_cell
        );
    }
    Ok(c)
}

/// "increments: 4 taken of 1 requested (adaptive, at most 6 splits) at load
/// 0.5, 0.75, 0.875, 1; stepped back at 0 (step 1, certified-invalid, cell 0)".
fn increments_line(r: &hocurve::curve::CurveReport) -> String {
    let mut s = format!("increments: {} taken of {} requested", r.increments_taken(), r.increments);
    s += &if r.adaptive { format!(" (adaptive, at most {} splits)", r.max_splits) } else { " (adaptive off)".into() };
    if r.increments_taken() != r.increments || !r.step_backs.is_empty() {
        let loads: Vec<String> = r.load_fractions.iter().map(|l| format!("{l}")).collect();
        s += &format!(" at load {}", loads.join(", "));
    }
    for (i, b) in r.step_backs.iter().enumerate() {
        s += if i == 0 { "; stepped back at " } else { ", " };
        s += &format!("{} (step {}, {}", b.load, b.step, b.reason.name());
        if let Some(c) = b.cell {
            s += &format!(", cell {c}");
        }
        s.push(')');
    }
    s
}

/// "linear solver: 2 of 10 solves fell back: solve 4 by pcg-restarted
/// (preconditioner-not-positive-definite), solve 7 by direct (stagnation)".
fn fallbacks_line(r: &hocurve::curve::CurveReport) -> String {
    let list: Vec<String> = (r.solves.solved_by.iter().zip(&r.solves.fallback).enumerate())
        .filter_map(|(i, (by, f))| f.map(|f| format!("solve {} by {} ({})", i + 1, by.name(), f.name())))
        .collect();
    format!("linear solver: {} of {} solves fell back: {}", r.solves.fallbacks(), r.solves.len(), list.join(", "))
}

fn cmd_demo(argv: &[String]) -> Result<()> {
    let args = Args::parse(
        argv,
        &["order", "output-dir", "increments", "poisson", "formulation", "material", "adaptive", "max-splits"],
    )?;
    let dir = PathBuf::from(args.get("output-dir").unwrap_or("."));
    std::fs::create_dir_all(&dir).map_err(|e| Error::Io(format!("cannot create {}: {e}", dir.display())))?;
    let opts = options_from(&args, 4)?;
    let c2 = cases::cylinder_channel_2d(48, 8, 100.0);
    let c3 = cases::sphere_in_box_3d(3, 3);
    let mut reports = Vec::new();
    for (case, file) in [(&c2, "demo-2d.vtu"), (&c3, "demo-3d.vtu")] {
        eprintln!("[{}] {}", case.name, case.description);
        let mut mesh = case.mesh.clone();
        mesh.retain_tags(|d, t| case.projector.get(d, t).is_some());
        let curved = run_case(&case.name, &mesh, &case.projector, &opts)?;
        let path = dir.join(file);
        write_mesh(&path, &curved)?;
        eprintln!("[{}] wrote {}", case.name, path.display());
        reports.push((case.name.clone(), report::curve_report_json(&curved.report, opts.spacing, Some(&path))));
    }
    let path = dir.join("demo-report.json");
    let body = format!(
        "{{\n{}\n}}\n",
        reports
            .iter()
            .map(|(n, r)| format!("  \"{}\": {}", report::json_escape(n), indent(r)))
            .collect::<Vec<_>>()
            .join(",\n")
    );
    write_text_atomic(&path, &body)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

fn cmd_study(argv: &[String]) -> Result<()> {
    let quick = argv.iter().any(|a| a == "--quick");
    let rest: Vec<String> = argv.iter().filter(|a| *a != "--quick").cloned().collect();
    let args = Args::parse(&rest, &["output-dir"])?;
    let dir = PathBuf::from(args.get("output-dir").unwrap_or("."));
    std::fs::create_dir_all(&dir).map_err(|e| Error::Io(format!("cannot create {}: {e}", dir.display())))?;
    let config = if quick { study::StudyConfig::quick() } else { study::StudyConfig::full() };
    let t = std::time::Instant::now();
    let study = study::run(&config);
    print!("{}", study.table());
    eprintln!("study: {} runs in {:.1} s", study.cells.len(), t.elapsed().as_secs_f64());
    write_text_atomic(&dir.join("study.csv"), &study.csv())?;
    for (name, svg) in study.plots() {
        write_text_atomic(&dir.join(name), &svg)?;
    }
    eprintln!("wrote {}/study.csv and the plots", dir.display());
    Ok(())
}

/// `hocurve curve`; with `parallel` and `ranks` set, its elastic stages
/// spread over the processes of an MPI run (the report says how many).
fn cmd_curve(argv: &[String], parallel: Parallel, ranks: Option<usize>) -> Result<()> {
    let args = Args::parse(
        argv,
        &[
            "order",
            "geometry",
            "formulation",
            "material",
            "young",
            "poisson",
            "increments",
            "spacing",
            "solver",
            "caps",
            "retry",
            "repair",
            "adaptive",
            "max-splits",
            "condense",
            "optimize",
            "tangent-first",
            "tolerance",
            "max-iterations",
            "output",
            "report",
            "partitioned",
        ],
    )?;
    let input = match args.positional.as_slice() {
        [one] => PathBuf::from(one),
        [] => return Err(Error::InvalidInput("curve needs an input .msh file".into())),
        more => return Err(Error::InvalidInput(format!("curve takes one input file, got {}", more.len()))),
    };
    let (output, partitioned) = curve_output(&args, ranks)?;
    if args.get("order").is_none() {
        return Err(Error::InvalidInput("curve needs --order P".into()));
    }
    let opts = CurveOptions { parallel, ..options_from(&args, 2)? };
    let mut projector = ShapeProjector::new();
    for g in args.all("geometry") {
        let (tag, shape) =
            g.split_once('=').ok_or_else(|| Error::InvalidInput(format!("--geometry '{g}': expected TAG=SHAPE")))?;
        let tag: i32 = tag
            .trim()
            .parse()
            .map_err(|_| Error::InvalidInput(format!("--geometry '{g}': '{tag}' is not an integer tag")))?;
        projector.insert(tag, Shape::parse(shape)?);
    }
    // Fail before computing if an output cannot be written.
    for p in std::iter::once(output.as_path()).chain(args.get("report").map(Path::new)) {
        check_directory_exists(p)?;
    }
    let msh = io::gmsh::read_msh(&input)?;
    let mut mesh = io::gmsh::to_linear_mesh(&msh)?;
    for (&(dim, tag), shape) in projector.iter() {
        let found =
            if dim == mesh.dim - 1 { mesh.facet_tags.contains(&tag) } else { mesh.feature_edge_tags.contains(&tag) };
        if !found {
            return Err(Error::InvalidInput(format!(
                "--geometry {tag}={shape}: no boundary {} of {} has entity tag {tag}",
                if dim == mesh.dim - 1 { "facet" } else { "feature curve" },
                input.display()
            )));
        }
    }
    // Facets and feature edges whose tag has no shape stay straight.
    mesh.retain_tags(|d, t| projector.get(d, t).is_some());
    let curved = run_case(&input.display().to_string(), &mesh, &projector, &opts)?;
    match ranks.filter(|_| partitioned) {
        Some(parts) => {
            io::write_mesh_partitioned(&output, &curved.mesh, &hocurve::solver::partition(&curved.mesh, parts)?, parts)?
        }
        None => write_mesh(&output, &curved)?,
    }
    eprintln!("wrote {}", output.display());
    if let Some(r) = args.get("report") {
        write_curve_report(Path::new(r), &curved, opts.spacing, &output, ranks)?;
    }
    Ok(())
}

/// The output file of `curve`, and whether it is written in gmsh's
/// partitioned format, one part per process (hocurve-mpi only).
fn curve_output(args: &Args, ranks: Option<usize>) -> Result<(PathBuf, bool)> {
    let output = PathBuf::from(
        args.get("output").ok_or_else(|| Error::InvalidInput("curve needs --output OUT.msh|OUT.vtu".into()))?,
    );
    io::check_mesh_extension(&output)?;
    let partitioned = args.on_off("partitioned")?.unwrap_or(false);
    if partitioned && ranks.is_none() {
        return Err(Error::InvalidInput("--partitioned on: only hocurve-mpi writes partitioned meshes".into()));
    }
    if partitioned && output.extension().and_then(|e| e.to_str()) != Some("msh") {
        return Err(Error::InvalidInput("--partitioned on writes gmsh's format: the output must end in .msh".into()));
    }
    Ok((output, partitioned))
}

/// The JSON report of a `curve` run, with the number of MPI processes when
/// it had several (`ranks`).
fn write_curve_report(
    path: &Path,
    curved: &CurvedMesh,
    spacing: NodeSpacing,
    output: &Path,
    ranks: Option<usize>,
) -> Result<()> {
    let mut text = report::curve_report_json(&curved.report, spacing, Some(output));
    if let Some(n) = ranks {
        text = text.replacen('{', &format!("{{\n  \"ranks\": {n},"), 1);
    }
    write_text_atomic(path, &(text + "\n"))?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

/// An error if the directory `path` would be written in does not exist.
fn check_directory_exists(path: &Path) -> Result<()> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.is_dir() {
        return Err(Error::Io(format!("cannot write {}: directory {} does not exist", path.display(), dir.display())));
    }
    Ok(())
}

fn cmd_quality(argv: &[String]) -> Result<()> {
    let args = Args::parse(argv, &["report"])?;
    let input = match args.positional.as_slice() {
        [one] => PathBuf::from(one),
        _ => return Err(Error::InvalidInput("quality needs exactly one .msh file".into())),
    };
    let msh = io::gmsh::read_msh(&input)?;
    let (simplex, order, coords, gmsh_cells) = io::gmsh::high_order_cells(&msh)?;
    // gmsh's Lagrange elements interpolate at equispaced reference nodes.
    let nodes = NodeSet::new(simplex, order, NodeSpacing::Equispaced);
    let perm = ordering::permutation(&ordering::gmsh_multi_indices(simplex, order), &nodes.multi)
        .ok_or_else(|| Error::Io("internal: gmsh ordering does not match the node set".into()))?;
    let npc = nodes.len();
    let cells: Vec<usize> = gmsh_cells.chunks_exact(npc).flat_map(|c| perm.iter().map(move |&k| c[k])).collect();
    let basis = LagrangeBasis::new(&nodes);
    let cache = quality::sampling_cache(&basis);
    let mut q = quality::summarize(&quality::cell_qualities(&cache, &coords, None, &cells, None));
    quality::add_certified(&mut q, &quality::certify_cells(&basis, &coords, &cells));
    let body = format!(
        "{{\n  \"file\": \"{}\",\n  \"order\": {order},\n  \"cells\": {},\n  \"nodes\": {},\n{}\n}}",
        report::json_escape(&input.display().to_string()),
        cells.len() / npc,
        coords.len() / simplex.dim(),
        report::quality_json(&q)
    );
    println!("{body}");
    if let Some(r) = args.get("report") {
        write_text_atomic(Path::new(r), &(body + "\n"))?;
    }
    Ok(())
}

/// Write the curved mesh with its cell qualities.
fn write_mesh(path: &Path, curved: &CurvedMesh) -> Result<()> {
    io::write_mesh(path, &curved.mesh, Some(&curved.cell_quality))
}

fn write_text_atomic(path: &Path, text: &str) -> Result<()> {
    let tmp = path.with_extension("tmp");
    let res = std::fs::File::create(&tmp)
        .and_then(|mut f| f.write_all(text.as_bytes()).and_then(|_| f.sync_all()))
        .and_then(|_| std::fs::rename(&tmp, path));
    res.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::Io(format!("cannot write {}: {e}", path.display()))
    })
}

fn indent(s: &str) -> String {
    s.replace('\n', "\n  ")
}
