//! Fuzz target: bytes → a sequence of `hoc_*` calls on two handles, through
//! the library's own `extern "C"` functions, with arbitrary arguments.
//!
//! The harness keeps its side of the contract (every buffer is as long as the
//! count it passes, unless the count is above the documented limit of
//! 2^32 − 1, which must be rejected before the buffer is read; callbacks write
//! exactly what they are given) and checks the library's side after every call:
//! - the status is a defined code (0..=9); `HOC_ERROR_PANIC` (an internal panic
//!   caught at the boundary) counts as a bug;
//! - a failure leaves a message in `hoc_mesh_last_error`, a success an empty one;
//! - a failed call leaves the nodes of the handle bitwise as they were;
//! - a failed create returns no handle.
//! Crashes, aborts, memory errors (AddressSanitizer) and leaks (LeakSanitizer:
//! both handles are destroyed at the end of every input) are bugs too.
//!
//! Arguments whose only effect is a longer run are bounded: increments ≤ 3,
//! Newton iterations ≤ 30, threads ≤ 2, at most 4 runs and 64 calls per input.
#![no_main]

use std::ffi::{c_char, c_int, c_void, CStr};
use std::ptr::{null, null_mut};

use hocurve::ffi::*;
use libfuzzer_sys::fuzz_target;

/// Reads the fuzzer's bytes; zeros once they run out.
struct Bytes<'a> {
    data: &'a [u8],
}

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        match self.data.split_first() {
            Some((&b, rest)) => {
                self.data = rest;
                b
            }
            None => 0,
        }
    }
    fn raw<const N: usize>(&mut self) -> [u8; N] {
        let mut b = [0u8; N];
        for x in b.iter_mut() {
            *x = self.u8();
        }
        b
    }
    fn below(&mut self, n: usize) -> usize {
        self.u8() as usize % n.max(1)
    }
    fn pick<T: Copy>(&mut self, options: &[T]) -> T {
        options[self.below(options.len())]
    }
    fn chance(&mut self, one_in: u8) -> bool {
        self.u8() % one_in == 0
    }
    fn int(&mut self, interesting: &[c_int]) -> c_int {
        if self.chance(8) {
            c_int::from_le_bytes(self.raw())
        } else {
            self.pick(interesting)
        }
    }
    fn real(&mut self) -> f64 {
        const R: [f64; 16] = [
            1.0,
            1e5,
            0.3,
            0.45,
            0.0,
            -0.1,
            0.5,
            0.49999,
            f64::NAN,
            f64::INFINITY,
            -1.0,
            1e300,
            1e-300,
            5e-324,
            -0.0,
            2.0,
        ];
        if self.chance(6) {
            f64::from_le_bytes(self.raw())
        } else {
            self.pick(&R)
        }
    }
    /// A count to pass for a buffer of `actual` items: the true one, a smaller
    /// one, or one above the limit (never one that would overrun the buffer).
    fn count(&mut self, actual: usize) -> usize {
        match self.u8() % 8 {
            0 => 0,
            1 => actual.saturating_sub(1),
            2 => 1 << 40,
            3 => usize::MAX,
            4 => usize::MAX / 3,
            _ => actual,
        }
    }
    /// A count near `actual` for an output buffer of `actual + 1` items.
    fn out_count(&mut self, actual: usize) -> usize {
        match self.u8() % 6 {
            0 => 0,
            1 => actual + 1,
            2 => actual.saturating_sub(1),
            3 => usize::MAX,
            _ => actual,
        }
    }
    fn index(&mut self, n: usize) -> i64 {
        match self.u8() % 10 {
            0 => -1,
            1 => n as i64,
            2 => i64::MIN,
            3 => 1 << 62,
            _ => self.below(n.max(1)) as i64,
        }
    }
}

/// The linear meshes the calls start from.
struct Base {
    dim: usize,
    coords: Vec<f64>,
    cells: Vec<i64>,
}

fn bases() -> Vec<Base> {
    let mut disk = vec![0.0, 0.0];
    let mut disk_cells = Vec::new();
    for k in 0..8 {
        let a = k as f64 * std::f64::consts::FRAC_PI_4;
        disk.extend([a.cos(), a.sin()]);
        disk_cells.extend([0, 1 + k, 1 + (k + 1) % 8]);
    }
    let mut cube = Vec::new();
    for i in 0..8 {
        cube.extend([(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64]);
    }
    vec![
        Base { dim: 2, coords: vec![0., 0., 1., 0., 1., 1., 0., 1.], cells: vec![0, 1, 2, 0, 2, 3] },
        Base { dim: 2, coords: disk, cells: disk_cells },
        Base { dim: 3, coords: vec![0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1.], cells: vec![0, 1, 2, 3] },
        Base {
            dim: 3,
            coords: cube,
            cells: vec![0, 1, 3, 7, 0, 1, 5, 7, 0, 2, 3, 7, 0, 2, 6, 7, 0, 4, 5, 7, 0, 4, 6, 7],
        },
        Base {
            dim: 3,
            coords: vec![0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1., 0.25, 0.25, 0.25],
            cells: vec![0, 1, 2, 4, 0, 1, 3, 4, 0, 2, 3, 4, 1, 2, 3, 4],
        },
    ]
}

/// Facets in exactly one cell, and (3D) the edges of those facets.
fn boundary(dim: usize, cells: &[i64]) -> (Vec<i64>, Vec<i64>) {
    let mut count = std::collections::BTreeMap::<Vec<i64>, usize>::new();
    for c in cells.chunks_exact(dim + 1) {
        for skip in 0..=dim {
            let mut f: Vec<i64> = (0..=dim).filter(|&k| k != skip).map(|k| c[k]).collect();
            f.sort_unstable();
            *count.entry(f).or_default() += 1;
        }
    }
    let facets: Vec<Vec<i64>> = count.into_iter().filter(|(_, n)| *n == 1).map(|(f, _)| f).collect();
    let mut edges = std::collections::BTreeSet::new();
    if dim == 3 {
        for f in &facets {
            edges.extend([[f[0], f[1]], [f[1], f[2]], [f[0], f[2]]]);
        }
    }
    (facets.concat(), edges.into_iter().flatten().collect())
}

/// What the harness's projector does, and the mesh dimension (how many
/// doubles a point has). Passed as `user_data`.
#[derive(Clone, Copy)]
struct ProjMode {
    mode: u8,
    dim: usize,
}

const PROJ_MODES: u8 = 8;
static PROJ: [[ProjMode; 2]; PROJ_MODES as usize] = {
    let mut t = [[ProjMode { mode: 0, dim: 2 }, ProjMode { mode: 0, dim: 3 }]; PROJ_MODES as usize];
    let mut m = 0;
    while m < PROJ_MODES as usize {
        t[m] = [ProjMode { mode: m as u8, dim: 2 }, ProjMode { mode: m as u8, dim: 3 }];
        m += 1;
    }
    t
};

unsafe extern "C" fn projector(
    ud: *mut c_void,
    _entity_dim: c_int,
    _entity_tag: c_int,
    n: usize,
    points: *const f64,
    projected: *mut f64,
) -> c_int {
    let m = &*(ud as *const ProjMode);
    let len = n * m.dim;
    let x = std::slice::from_raw_parts(points, len);
    let y = std::slice::from_raw_parts_mut(projected, len);
    match m.mode {
        0 => y.copy_from_slice(x),
        1 => {
            // Onto the unit circle / sphere.
            for (p, q) in x.chunks_exact(m.dim).zip(y.chunks_exact_mut(m.dim)) {
                let r = p.iter().map(|v| v * v).sum::<f64>().sqrt();
                for (a, b) in p.iter().zip(q.iter_mut()) {
                    *b = if r > 0.0 { a / r } else { *a };
                }
            }
        }
        2 => return 3,
        3 => {
            y.copy_from_slice(x);
            if len > 0 {
                y[len / 2] = f64::NAN;
            }
        }
        4 => {
            y.copy_from_slice(x);
            if len > 0 {
                y[0] += 1e3;
            }
        }
        5 => {} // leaves the output as it was
        6 => {
            for (a, b) in x.iter().zip(y.iter_mut()) {
                *b = a * 1.01;
            }
        }
        _ => {
            y.copy_from_slice(x);
            if len > 0 {
                y[len - 1] = f64::INFINITY;
            }
        }
    }
    0
}

/// Cancel at (stage, step); 255 = never.
static PROGRESS: [[u8; 2]; 6] = [[255, 0], [0, 0], [1, 0], [2, 0], [2, 1], [3, 0]];

unsafe extern "C" fn progress(ud: *mut c_void, stage: c_int, step: c_int, _total: c_int) -> c_int {
    let m = &*(ud as *const [u8; 2]);
    c_int::from(c_int::from(m[0]) == stage && c_int::from(m[1]) == step)
}

static SOLVER: [u8; 4] = [0, 1, 2, 3];

unsafe extern "C" fn solver(
    ud: *mut c_void,
    n: i64,
    row_ptr: *const i64,
    col_idx: *const i64,
    values: *const f64,
    rhs: *const f64,
    x: *mut f64,
) -> c_int {
    let n = n as usize;
    let rp = std::slice::from_raw_parts(row_ptr, n + 1);
    let nnz = rp[n] as usize;
    let (ci, v) = (std::slice::from_raw_parts(col_idx, nnz), std::slice::from_raw_parts(values, nnz));
    let (b, x) = (std::slice::from_raw_parts(rhs, n), std::slice::from_raw_parts_mut(x, n));
    match *(ud as *const u8) {
        0 => return 1,
        1 => x.fill(f64::NAN),
        2 => {
            // A few Jacobi sweeps: an inaccurate but finite answer.
            for _ in 0..20 {
                let old = x.to_vec();
                for i in 0..n {
                    let (mut s, mut d) = (b[i], 0.0);
                    for k in rp[i] as usize..rp[i + 1] as usize {
                        let j = ci[k] as usize;
                        if j == i {
                            d = v[k];
                        } else {
                            s -= v[k] * old[j];
                        }
                    }
                    x[i] = if d != 0.0 { s / d } else { 0.0 };
                }
            }
        }
        _ => {} // keeps the initial guess
    }
    0
}

struct Slot {
    h: *mut HocMesh,
    dim: usize,
    facets: Vec<i64>,
    edges: Vec<i64>,
}

impl Default for Slot {
    fn default() -> Self {
        Slot { h: null_mut(), dim: 0, facets: Vec::new(), edges: Vec::new() }
    }
}

fn message(h: *const HocMesh) -> String {
    // SAFETY: NULL or a live handle; the string is NUL-terminated.
    unsafe { CStr::from_ptr(hoc_mesh_last_error(h)).to_string_lossy().into_owned() }
}

/// Nodes of a live handle, as bits.
fn nodes(h: *const HocMesh, dim: usize) -> Vec<u64> {
    let mut n = 0usize;
    unsafe {
        assert_eq!(hoc_mesh_node_count(h, &mut n), HOC_OK);
        let mut x = vec![0.0; n * dim];
        assert_eq!(hoc_mesh_get_nodes(h, HOC_ORDERING_NATIVE, n, x.as_mut_ptr()), HOC_OK);
        x.iter().map(|v| v.to_bits()).collect()
    }
}

fn counts(h: *const HocMesh) -> (usize, usize, usize) {
    let (mut nn, mut nc, mut npc) = (0, 0, 0);
    unsafe {
        assert_eq!(hoc_mesh_node_count(h, &mut nn), HOC_OK);
        assert_eq!(hoc_mesh_cell_count(h, &mut nc, &mut npc), HOC_OK);
    }
    (nn, nc, npc)
}

/// The status and message of a call on `h` (NULL: the thread's message).
fn check(what: &str, st: HocStatus, h: *const HocMesh) {
    assert!((0..=9).contains(&st), "{what}: status {st} ({})", message(h));
    let m = message(h);
    if st == HOC_OK {
        assert!(m.is_empty(), "{what}: success with message {m:?}");
    } else {
        assert!(!m.is_empty(), "{what}: status {st} without a message");
    }
}

fn temp_dir() -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("hocurve-fuzz-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&d);
    d
}

fn one_call(r: &mut Bytes, slots: &mut [Slot; 2], bases: &[Base], runs: &mut usize) {
    let s = r.below(2);
    let op = r.below(20);
    let (h, dim) = (slots[s].h, slots[s].dim);
    let before = (!h.is_null()).then(|| nodes(h, dim));
    let name;
    // SAFETY (whole match): every pointer passed is NULL, a live handle, or a
    // buffer at least as long as the count passed with it (counts above
    // 2^32 − 1 excepted: the library must reject those unread).
    let st = unsafe {
        match op {
            0 | 1 => {
                if !h.is_null() {
                    hoc_mesh_destroy(&mut slots[s].h);
                }
                let d = r.pick(&[2, 3, 2, 3, 2, 3, 1, 4, 0, -1, c_int::MIN]);
                let pool: Vec<&Base> = bases.iter().filter(|b| b.dim as c_int == d).collect();
                let base = if pool.is_empty() { &bases[0] } else { pool[r.below(pool.len())] };
                let (mut x, mut c) = (base.coords.clone(), base.cells.clone());
                let nv = x.len() / base.dim;
                for _ in 0..r.below(3) {
                    match r.below(5) {
                        0 => {
                            let i = r.below(x.len());
                            x[i] = r.real();
                        }
                        1 => {
                            let i = r.below(c.len());
                            c[i] = r.index(nv);
                        }
                        2 => c.extend_from_within(..base.dim + 1),
                        3 if c.len() > base.dim + 1 => c.truncate(c.len() - base.dim - 1),
                        _ => {
                            let (i, j) = (r.below(c.len()), r.below(c.len()));
                            c.swap(i, j);
                        }
                    }
                }
                let nv_claim = r.count(x.len() / base.dim);
                let nc_claim = r.count(c.len() / (base.dim + 1));
                let xp = if r.chance(16) { null() } else { x.as_ptr() };
                let cp = if r.chance(16) { null() } else { c.as_ptr() };
                let mut out: *mut HocMesh = null_mut();
                let outp = if r.chance(32) { null_mut() } else { &mut out as *mut _ };
                let st = hoc_mesh_create(d, nv_claim, xp, nc_claim, cp, outp);
                check("create", st, null());
                if st == HOC_OK {
                    let (f, e) = boundary(base.dim, &c);
                    slots[s] = Slot { h: out, dim: base.dim, facets: f, edges: e };
                } else {
                    assert!(out.is_null(), "a failed create returned a handle");
                }
                return;
            }
            2 => {
                if r.chance(4) {
                    assert_eq!(hoc_mesh_destroy(null_mut()), HOC_OK);
                } else {
                    assert_eq!(hoc_mesh_destroy(&mut slots[s].h), HOC_OK);
                    assert!(slots[s].h.is_null(), "destroy did not clear the handle");
                }
                return;
            }
            3 => {
                name = "set_boundary";
                let d = dim.max(2);
                let all = &slots[s].facets;
                let nf = all.len() / d;
                let mut f: Vec<i64> = if nf == 0 {
                    vec![0; d]
                } else {
                    let a = r.below(nf);
                    let b = a + r.below(nf - a + 1);
                    all[a * d..b * d].to_vec()
                };
                for _ in 0..r.below(3) {
                    match r.below(3) {
                        0 if !f.is_empty() => {
                            let i = r.below(f.len());
                            f[i] = r.index(16);
                        }
                        1 if !f.is_empty() => f.extend_from_within(..d),
                        _ => f.reverse(),
                    }
                }
                let n = f.len() / d;
                let tags: Vec<i32> = (0..n).map(|_| r.pick(&[1, 1, 2, 3, 0, -1, i32::MAX])).collect();
                let claim = r.count(n);
                let fp = if r.chance(16) { null() } else { f.as_ptr() };
                let tp = if r.chance(16) { null() } else { tags.as_ptr() };
                hoc_mesh_set_boundary(h, claim, fp, tp)
            }
            4 => {
                name = "set_feature_edges";
                let all = &slots[s].edges;
                let ne = all.len() / 2;
                let mut e: Vec<i64> = if ne == 0 {
                    vec![0, 1]
                } else {
                    let a = r.below(ne);
                    let b = a + r.below((ne - a + 1).min(4));
                    all[a * 2..b * 2].to_vec()
                };
                if r.chance(3) && !e.is_empty() {
                    let i = r.below(e.len());
                    e[i] = r.index(16);
                }
                if r.chance(4) && e.len() >= 2 {
                    e.extend_from_within(..2);
                }
                let n = e.len() / 2;
                let tags: Vec<i32> = (0..n).map(|_| r.pick(&[1, 7, -1])).collect();
                let claim = r.count(n);
                let ep = if r.chance(16) { null() } else { e.as_ptr() };
                hoc_mesh_set_feature_edges(h, claim, ep, tags.as_ptr())
            }
            5 => {
                name = "set_projector";
                let m = r.below(PROJ_MODES as usize + 1);
                if m == PROJ_MODES as usize || dim == 0 {
                    hoc_mesh_set_projector(h, None, null_mut())
                } else {
                    let ud = &PROJ[m][dim - 2] as *const ProjMode as *mut c_void;
                    hoc_mesh_set_projector(h, Some(projector), ud)
                }
            }
            6 => {
                name = "set_progress";
                let m = r.below(PROGRESS.len() + 1);
                if m == PROGRESS.len() {
                    hoc_mesh_set_progress(h, None, null_mut())
                } else {
                    hoc_mesh_set_progress(h, Some(progress), &PROGRESS[m] as *const _ as *mut c_void)
                }
            }
            7 => {
                name = "set_linear_solver";
                let m = r.below(SOLVER.len() + 2);
                if m >= SOLVER.len() {
                    hoc_mesh_set_linear_solver(h, None, null_mut())
                } else {
                    hoc_mesh_set_linear_solver(h, Some(solver), &SOLVER[m] as *const u8 as *mut c_void)
                }
            }
            8 => {
                name = "set_order";
                let p = r.int(&[1, 2, 3, 2, 4, 5, 10, 0, -1, 11, c_int::MAX, c_int::MIN]);
                let sp = r.int(&[0, 1, 0, 2, -1]);
                hoc_mesh_set_order(h, p, sp)
            }
            9 => {
                name = "set_material";
                let m = r.int(&[0, 1, 2, 3, 4, 5, 6, -1, c_int::MIN]);
                let (e, nu) = (r.real(), r.real());
                hoc_mesh_set_material(h, m, e, nu)
            }
            10 => {
                name = "set_formulation";
                hoc_mesh_set_formulation(h, r.int(&[0, 1, 2, 3, 4, 5, -1, c_int::MIN]))
            }
            11 => {
                name = "set_newton";
                let tol = r.real();
                hoc_mesh_set_newton(h, tol, r.pick(&[1, 2, 5, 30, 0, -1, c_int::MIN]))
            }
            12 => {
                name = "set_fibres";
                let nc = if h.is_null() { 0 } else { counts(h).1 };
                let f: Vec<f64> = (0..3 * (nc + 1)).map(|_| r.real()).collect();
                // At most nc + 1 (the buffer), or above the limit (rejected unread).
                let n = if r.chance(8) { 1 << 40 } else { r.out_count(nc).min(nc + 1) };
                if r.chance(4) {
                    hoc_mesh_set_fibres(h, n, null())
                } else {
                    hoc_mesh_set_fibres(h, n, f.as_ptr())
                }
            }
            13 => {
                // The setters that keep the nodes first: only the last call's
                // failure is checked against the nodes from before the three.
                name = "set_threads+condensation+repair+caps";
                // Counts the library accepts are held to 2 (a pool of thousands
                // of threads only makes the run long); larger ones must be refused.
                let t = r.int(&[0, 1, 2, -1, c_int::MIN]);
                let st = hoc_mesh_set_threads(h, if (3..=4096).contains(&t) { 2 } else { t });
                check("set_threads", st, h);
                let st = hoc_mesh_set_static_condensation(h, r.int(&[1, 0, 2, -1]));
                check("set_static_condensation", st, h);
                let st = hoc_mesh_set_repair(h, r.int(&[1, 0, 2, -1]));
                check("set_repair", st, h);
                hoc_mesh_set_remove_caps(h, r.int(&[0, 1, 2, -1]))
            }
            14 | 15 => {
                name = "run_increments";
                if *runs >= 4 {
                    return;
                }
                *runs += 1;
                hoc_mesh_run_increments(h, r.int(&[1, 1, 2, 3, 0, -1, c_int::MIN]))
            }
            16 => {
                name = "quality";
                let mut q = std::mem::MaybeUninit::<HocQuality>::uninit();
                let qp = if r.chance(8) { null_mut() } else { q.as_mut_ptr() };
                let st = hoc_mesh_quality(h, qp);
                check("quality", st, h);
                let mut rep = std::mem::MaybeUninit::<HocRepair>::uninit();
                let rp = if r.chance(8) { null_mut() } else { rep.as_mut_ptr() };
                let st = hoc_mesh_repair_summary(h, rp);
                check("repair_summary", st, h);
                let nc = if h.is_null() { 0 } else { counts(h).1 };
                let mut out = vec![0.0; nc + 1];
                let n = r.out_count(nc);
                let op = if r.chance(8) { null_mut() } else { out.as_mut_ptr() };
                hoc_mesh_cell_quality(h, r.int(&[1, 2, 3, 0, 4, -1]), n, op)
            }
            17 => {
                name = "get_nodes/cells";
                let (nn, nc, npc) = if h.is_null() { (0, 0, 0) } else { counts(h) };
                let mut x = vec![0.0; (nn + 1) * dim.max(2)];
                let n = r.out_count(nn);
                let st = hoc_mesh_get_nodes(h, r.int(&[0, 1, 2, 0, 3]), n, if r.chance(8) { null_mut() } else { x.as_mut_ptr() });
                check("get_nodes", st, h);
                let mut c = vec![0i64; nc * npc + 1];
                let len = r.out_count(nc * npc);
                let st = hoc_mesh_get_cells(h, r.int(&[0, 1, 2, 3, -1]), len, c.as_mut_ptr());
                check("get_cells", st, h);
                let mut ic = vec![0i64; nc + 1];
                hoc_mesh_get_input_cells(h, r.out_count(nc), if r.chance(8) { null_mut() } else { ic.as_mut_ptr() })
            }
            18 => {
                name = "write";
                let dir = temp_dir();
                let path: Option<Vec<u8>> = match r.below(7) {
                    0 => Some(dir.join("f.msh").display().to_string().into_bytes()),
                    1 => Some(dir.join("f.vtu").display().to_string().into_bytes()),
                    2 => Some(dir.join("f.xyz").display().to_string().into_bytes()),
                    3 => Some(Vec::new()),
                    4 => Some(b"/nonexistent-hocurve-dir/f.msh".to_vec()),
                    5 => Some(b"f\xff\xfe.msh".to_vec()),
                    _ => None,
                };
                let c = path.map(|p| std::ffi::CString::new(p).unwrap());
                hoc_mesh_write(h, c.as_ref().map_or(null(), |c| c.as_ptr()))
            }
            _ => {
                let st = r.int(&[0, 1, 5, 10, 11, -1, c_int::MIN]);
                let p: *const c_char = hoc_status_string(st);
                assert!(!CStr::from_ptr(p).to_bytes().is_empty());
                assert!(!CStr::from_ptr(hoc_version()).to_bytes().is_empty());
                let _ = message(null());
                return;
            }
        }
    };
    check(name, st, h);
    if h.is_null() {
        assert_eq!(st, HOC_ERROR_NULL_POINTER, "{name} on a NULL handle");
    } else if st != HOC_OK {
        assert_eq!(before, Some(nodes(h, dim)), "{name} failed with status {st} and changed the nodes");
    }
}

fuzz_target!(|data: &[u8]| {
    let bases = bases();
    let mut r = Bytes { data };
    let mut slots: [Slot; 2] = Default::default();
    let mut runs = 0;
    for _ in 0..64 {
        if r.data.is_empty() {
            break;
        }
        one_call(&mut r, &mut slots, &bases, &mut runs);
    }
    for s in &mut slots {
        // SAFETY: a live handle or NULL.
        unsafe { hoc_mesh_destroy(&mut s.h) };
    }
});
