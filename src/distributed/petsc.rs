//! The PETSc calls the distributed solve makes, bound by hand (PETSc 3.18
//! as Debian builds it: 32-bit `PetscInt`, real double `PetscScalar`), and
//! the one object built on them, [`PetscSystem`].
//!
//! Each process hands its cells' part of the system (a local matrix and
//! right-hand side, as the serial assembly makes them on its sub-mesh) with
//! the map from its local rows to the global ones. PETSc keeps that as an
//! unassembled `MATIS`, converts it to a distributed `MATAIJ` with block
//! size d, and solves with CG and smoothed-aggregation AMG (`PCGAMG`) given
//! the rigid-body modes of the owned nodes as its near-null space. Options
//! from `PETSC_OPTIONS` or the command line override these (`KSPSetFromOptions`).

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::ptr;

use mpi::ffi::MPI_Comm;

use crate::solver::FullCsrPattern;
use crate::sparse::SymmetricCsc;

type PetscErrorCode = c_int;
type PetscInt = i32;
type PetscScalar = f64;
type PetscReal = f64;
type Mat = *mut c_void;
type Vec = *mut c_void;
type Ksp = *mut c_void;
type Pc = *mut c_void;
type VecScatter = *mut c_void;
type MatNullSpace = *mut c_void;
type L2G = *mut c_void;

const PETSC_COPY_VALUES: c_int = 0;
const INSERT_VALUES: c_int = 1;
const ADD_VALUES: c_int = 2;
const MAT_FINAL_ASSEMBLY: c_int = 0;
const MAT_INITIAL_MATRIX: c_int = 0;
const MAT_REUSE_MATRIX: c_int = 1;
const SCATTER_FORWARD: c_int = 0;
const PETSC_DEFAULT: PetscInt = -2;
const PETSC_TRUE: c_int = 1;
const PC_MG_GALERKIN_NONE: c_int = 3;

#[link(name = "petsc_real")]
extern "C" {
    /// The communicator PETSc initialises on (MPI_COMM_WORLD unless set before).
    static mut PETSC_COMM_WORLD: MPI_Comm;
    fn PetscInitializeNoArguments() -> PetscErrorCode;
    fn PetscInitialized(isinitialized: *mut c_int) -> PetscErrorCode;
    fn PetscFinalize() -> PetscErrorCode;

    fn ISLocalToGlobalMappingCreate(
        comm: MPI_Comm,
        bs: PetscInt,
        n: PetscInt,
        indices: *const PetscInt,
        mode: c_int,
        out: *mut L2G,
    ) -> PetscErrorCode;
    fn ISLocalToGlobalMappingDestroy(m: *mut L2G) -> PetscErrorCode;

    fn MatCreateIS(
        comm: MPI_Comm,
        bs: PetscInt,
        m: PetscInt,
        n: PetscInt,
        big_m: PetscInt,
        big_n: PetscInt,
        rmap: L2G,
        cmap: L2G,
        a: *mut Mat,
    ) -> PetscErrorCode;
    fn MatCreateSeqAIJWithArrays(
        comm: MPI_Comm,
        m: PetscInt,
        n: PetscInt,
        i: *mut PetscInt,
        j: *mut PetscInt,
        a: *mut PetscScalar,
        mat: *mut Mat,
    ) -> PetscErrorCode;
    fn MatISSetLocalMat(a: Mat, local: Mat) -> PetscErrorCode;
    fn MatAssemblyBegin(a: Mat, t: c_int) -> PetscErrorCode;
    fn MatAssemblyEnd(a: Mat, t: c_int) -> PetscErrorCode;
    fn MatConvert(a: Mat, newtype: *const c_char, reuse: c_int, out: *mut Mat) -> PetscErrorCode;
    fn MatSetNearNullSpace(a: Mat, sp: MatNullSpace) -> PetscErrorCode;
    fn MatNullSpaceCreateRigidBody(coords: Vec, sp: *mut MatNullSpace) -> PetscErrorCode;
    fn MatNullSpaceDestroy(sp: *mut MatNullSpace) -> PetscErrorCode;
    fn MatDestroy(a: *mut Mat) -> PetscErrorCode;
    #[allow(clippy::too_many_arguments)]
    fn MatCreateAIJ(
        comm: MPI_Comm,
        m: PetscInt,
        n: PetscInt,
        big_m: PetscInt,
        big_n: PetscInt,
        d_nz: PetscInt,
        d_nnz: *const PetscInt,
        o_nz: PetscInt,
        o_nnz: *const PetscInt,
        a: *mut Mat,
    ) -> PetscErrorCode;
    fn MatSetBlockSizes(a: Mat, rbs: PetscInt, cbs: PetscInt) -> PetscErrorCode;
    fn MatSetValues(
        a: Mat,
        m: PetscInt,
        idxm: *const PetscInt,
        n: PetscInt,
        idxn: *const PetscInt,
        v: *const PetscScalar,
        mode: c_int,
    ) -> PetscErrorCode;
    fn MatPtAP(a: Mat, p: Mat, reuse: c_int, fill: PetscReal, c: *mut Mat) -> PetscErrorCode;
    fn PCMGSetLevels(pc: Pc, levels: PetscInt, comms: *mut MPI_Comm) -> PetscErrorCode;
    fn PCMGSetGalerkin(pc: Pc, t: c_int) -> PetscErrorCode;
    fn PCMGSetInterpolation(pc: Pc, l: PetscInt, p: Mat) -> PetscErrorCode;
    fn PCMGGetCoarseSolve(pc: Pc, ksp: *mut Ksp) -> PetscErrorCode;
    fn PCMGGetSmoother(pc: Pc, l: PetscInt, ksp: *mut Ksp) -> PetscErrorCode;

    fn VecCreateMPI(comm: MPI_Comm, n: PetscInt, big_n: PetscInt, v: *mut Vec) -> PetscErrorCode;
    fn VecSetBlockSize(v: Vec, bs: PetscInt) -> PetscErrorCode;
    fn VecSet(v: Vec, a: PetscScalar) -> PetscErrorCode;
    fn VecSetValues(v: Vec, n: PetscInt, ix: *const PetscInt, y: *const PetscScalar, mode: c_int) -> PetscErrorCode;
    fn VecAssemblyBegin(v: Vec) -> PetscErrorCode;
    fn VecAssemblyEnd(v: Vec) -> PetscErrorCode;
    fn VecGetArrayRead(v: Vec, a: *mut *const PetscScalar) -> PetscErrorCode;
    fn VecRestoreArrayRead(v: Vec, a: *mut *const PetscScalar) -> PetscErrorCode;
    fn VecGetLocalSize(v: Vec, n: *mut PetscInt) -> PetscErrorCode;
    fn VecGetOwnershipRange(v: Vec, lo: *mut PetscInt, hi: *mut PetscInt) -> PetscErrorCode;
    fn VecDestroy(v: *mut Vec) -> PetscErrorCode;
    fn VecScatterCreateToAll(v: Vec, ctx: *mut VecScatter, out: *mut Vec) -> PetscErrorCode;
    fn VecScatterBegin(ctx: VecScatter, x: Vec, y: Vec, addv: c_int, mode: c_int) -> PetscErrorCode;
    fn VecScatterEnd(ctx: VecScatter, x: Vec, y: Vec, addv: c_int, mode: c_int) -> PetscErrorCode;
    fn VecScatterDestroy(ctx: *mut VecScatter) -> PetscErrorCode;

    fn KSPCreate(comm: MPI_Comm, ksp: *mut Ksp) -> PetscErrorCode;
    fn KSPSetOperators(ksp: Ksp, a: Mat, p: Mat) -> PetscErrorCode;
    fn KSPSetType(ksp: Ksp, t: *const c_char) -> PetscErrorCode;
    fn KSPGetPC(ksp: Ksp, pc: *mut Pc) -> PetscErrorCode;
    fn PCSetType(pc: Pc, t: *const c_char) -> PetscErrorCode;
    fn KSPSetTolerances(
        ksp: Ksp,
        rtol: PetscReal,
        abstol: PetscReal,
        dtol: PetscReal,
        maxits: PetscInt,
    ) -> PetscErrorCode;
    fn KSPSetInitialGuessNonzero(ksp: Ksp, flg: c_int) -> PetscErrorCode;
    fn KSPSetFromOptions(ksp: Ksp) -> PetscErrorCode;
    fn KSPSolve(ksp: Ksp, b: Vec, x: Vec) -> PetscErrorCode;
    fn KSPGetIterationNumber(ksp: Ksp, its: *mut PetscInt) -> PetscErrorCode;
    fn KSPGetConvergedReason(ksp: Ksp, reason: *mut c_int) -> PetscErrorCode;
    fn KSPGetConvergedReasonString(ksp: Ksp, s: *mut *const c_char) -> PetscErrorCode;
    fn KSPDestroy(ksp: *mut Ksp) -> PetscErrorCode;
}

/// A PETSc call's error code as a message naming the call.
fn check(code: PetscErrorCode, call: &str) -> Result<(), String> {
    match code {
        0 => Ok(()),
        e => Err(format!("PETSc: {call} returned error {e}")),
    }
}

/// Start PETSc on the already initialised MPI (`PETSC_COMM_WORLD` is
/// `MPI_COMM_WORLD`), unless it runs already.
pub fn initialize() -> Result<(), String> {
    initialize_on(None)
}

/// Initialise PETSc unless it is: on `comm` (collective over it) when
/// given, else on `MPI_COMM_WORLD`.
pub fn initialize_on(comm: Option<MPI_Comm>) -> Result<(), String> {
    let mut done = 0;
    // SAFETY: plain calls with a valid out-pointer; PETSC_COMM_WORLD may be
    // set before PetscInitialize, and is read by nothing else until then.
    unsafe {
        check(PetscInitialized(&mut done), "PetscInitialized")?;
        if done == 0 {
            if let Some(comm) = comm {
                PETSC_COMM_WORLD = comm;
            }
            check(PetscInitializeNoArguments(), "PetscInitializeNoArguments")?;
        }
    }
    Ok(())
}

/// End PETSc (before MPI ends).
pub fn finalize() {
    // SAFETY: called once, after every PETSc object was destroyed.
    unsafe {
        PetscFinalize();
    }
}

fn c_name(s: &str) -> CString {
    CString::new(s).expect("no NUL in PETSc type names")
}

/// One process's share of a distributed symmetric system, and the solver.
///
/// Built once per sparsity pattern: the local matrix's CSR arrays stay
/// owned here (PETSc reads them in place), so a new system only copies
/// values; the distributed matrix and the AMG hierarchy are rebuilt by
/// PETSc for each solve.
pub struct PetscSystem {
    comm: MPI_Comm,
    /// Local CSR (both triangles, sorted columns) of the local rows.
    row_ptr: std::vec::Vec<PetscInt>,
    col_idx: std::vec::Vec<PetscInt>,
    /// Per local CSR entry, the index of its value in the lower triangle's.
    source: std::vec::Vec<u32>,
    values: std::vec::Vec<PetscScalar>,
    /// Global row of each local row.
    global: std::vec::Vec<PetscInt>,
    n_owned: usize,
    n_global: usize,
    block: usize,
    /// Coordinates of the owned nodes (block-interleaved), for the rigid-body modes.
    owned_coords: std::vec::Vec<f64>,
    /// The global rows this process owns start here.
    first_owned: usize,
    l2g: L2G,
    local: Mat,
    is: Mat,
    aij: Mat,
    /// The P1 level of a two-level preconditioner, if there is one.
    coarse: Option<CoarseLevel>,
}

/// The P1 level: the prolongation from it, its Galerkin operator, and its
/// owned nodes' coordinates (for the rigid-body modes).
struct CoarseLevel {
    p: Mat,
    ac: Mat,
    owned_coords: std::vec::Vec<f64>,
    n_owned: usize,
    n_global: usize,
}

/// The P1 space of the vertices, the coarse level of the preconditioner:
/// the entries of the prolongation P (fine global row, coarse global
/// column, value) in this process's owned fine rows, and its coarse rows.
pub struct Coarse {
    pub entries: std::vec::Vec<(usize, usize, f64)>,
    pub n_owned: usize,
    pub n_global: usize,
    /// Coordinates of the owned coarse nodes, in their rows' order.
    pub owned_coords: std::vec::Vec<f64>,
}

// SAFETY: the PETSc objects are used from the thread that owns the
// PetscSystem only (the elastic stage runs its solves on one thread).
unsafe impl Send for PetscSystem {}
unsafe impl Sync for PetscSystem {}

/// The outcome of one solve.
pub struct Solved {
    pub iterations: usize,
    /// Every global row's value (gathered to every process).
    pub all: std::vec::Vec<f64>,
}

impl PetscSystem {
    /// `lower`: the local matrix's pattern, its lower triangle; `global`:
    /// the global row of each local row; this process owns the `n_owned`
    /// global rows from `first_owned`, of `n_global`; `block` the unknowns
    /// per node, and `owned_coords` the owned nodes' coordinates in the
    /// global rows' order.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        comm: MPI_Comm,
        lower: &SymmetricCsc,
        global: &[usize],
        first_owned: usize,
        n_owned: usize,
        n_global: usize,
        block: usize,
        owned_coords: std::vec::Vec<f64>,
        coarse: Option<Coarse>,
    ) -> Result<PetscSystem, String> {
        let to_int = |v: usize| PetscInt::try_from(v).map_err(|_| format!("{v} does not fit PETSc's 32-bit integers"));
        // Both triangles, as PETSc's AIJ wants them; the map from each entry
        // to its lower-triangle value is kept, the rest dropped.
        let full = FullCsrPattern::from_lower_csc(lower);
        let row_ptr: std::vec::Vec<PetscInt> = full.row_ptr.iter().map(|&v| to_int(v)).collect::<Result<_, _>>()?;
        let col_idx: std::vec::Vec<PetscInt> = full.col_idx.iter().map(|&v| to_int(v)).collect::<Result<_, _>>()?;
        let source: std::vec::Vec<u32> = full.source.iter().map(|&k| k as u32).collect();
        drop(full);
        let global: std::vec::Vec<PetscInt> = global.iter().map(|&v| to_int(v)).collect::<Result<_, _>>()?;
        to_int(n_global)?;
        let values = vec![0.0; col_idx.len()];
        let mut s = PetscSystem {
            comm,
            source,
            row_ptr,
            col_idx,
            values,
            global,
            n_owned,
            n_global,
            block,
            owned_coords,
            first_owned,
            l2g: ptr::null_mut(),
            local: ptr::null_mut(),
            is: ptr::null_mut(),
            aij: ptr::null_mut(),
            coarse: None,
        };
        let n_local = s.global.len() as PetscInt;
        // SAFETY: the arrays outlive the objects that read them (both owned by `s`).
        unsafe {
            check(
                ISLocalToGlobalMappingCreate(comm, 1, n_local, s.global.as_ptr(), PETSC_COPY_VALUES, &mut s.l2g),
                "ISLocalToGlobalMappingCreate",
            )?;
            let (m, big) = (n_owned as PetscInt, n_global as PetscInt);
            check(MatCreateIS(comm, block as PetscInt, m, m, big, big, s.l2g, s.l2g, &mut s.is), "MatCreateIS")?;
            check(
                MatCreateSeqAIJWithArrays(
                    mpi::ffi::RSMPI_COMM_SELF,
                    n_local,
                    n_local,
                    s.row_ptr.as_mut_ptr(),
                    s.col_idx.as_mut_ptr(),
                    s.values.as_mut_ptr(),
                    &mut s.local,
                ),
                "MatCreateSeqAIJWithArrays",
            )?;
            check(MatISSetLocalMat(s.is, s.local), "MatISSetLocalMat")?;
        }
        if let Some(c) = coarse.filter(|c| c.n_global > 0) {
            s.coarse = Some(s.prolongation(c)?);
        }
        Ok(s)
    }

    /// The distributed P of `c`, with block size d both ways so that the
    /// Galerkin operator has nodal blocks.
    fn prolongation(&self, c: Coarse) -> Result<CoarseLevel, String> {
        let mut p: Mat = ptr::null_mut();
        let nz = (self.block + 1) as PetscInt;
        // SAFETY: each call's arrays outlive it; P is destroyed with the system.
        unsafe {
            check(
                MatCreateAIJ(
                    self.comm,
                    self.n_owned as PetscInt,
                    c.n_owned as PetscInt,
                    self.n_global as PetscInt,
                    c.n_global as PetscInt,
                    nz,
                    ptr::null(),
                    nz,
                    ptr::null(),
                    &mut p,
                ),
                "MatCreateAIJ",
            )?;
            check(MatSetBlockSizes(p, self.block as PetscInt, self.block as PetscInt), "MatSetBlockSizes")?;
            for &(r, col, v) in &c.entries {
                let (r, col) = (r as PetscInt, col as PetscInt);
                check(MatSetValues(p, 1, &r, 1, &col, &v, INSERT_VALUES), "MatSetValues")?;
            }
            check(MatAssemblyBegin(p, MAT_FINAL_ASSEMBLY), "MatAssemblyBegin")?;
            check(MatAssemblyEnd(p, MAT_FINAL_ASSEMBLY), "MatAssemblyEnd")?;
        }
        Ok(CoarseLevel {
            p,
            ac: ptr::null_mut(),
            owned_coords: c.owned_coords,
            n_owned: c.n_owned,
            n_global: c.n_global,
        })
    }

    /// The local matrix's values, from those of its lower triangle (in the
    /// order of the pattern given to [`Self::new`]), before [`Self::solve`].
    pub fn set_values(&mut self, lower: &[f64]) {
        for (v, &k) in self.values.iter_mut().zip(&self.source) {
            *v = lower[k as usize];
        }
    }

    /// Solve with the local right-hand side `rhs` (local rows; the global
    /// one is the sum over processes) from the guess `guess` (local rows;
    /// only owned rows are read), to ‖r‖ ≤ `rtol` ‖b‖.
    pub fn solve(&mut self, rhs: &[f64], guess: &[f64], rtol: f64) -> Result<Solved, String> {
        let (m, big) = (self.n_owned as PetscInt, self.n_global as PetscInt);
        let owned: std::vec::Vec<usize> = (0..self.global.len())
            .filter(|&l| (self.first_owned..self.first_owned + self.n_owned).contains(&(self.global[l] as usize)))
            .collect();
        let owned_rows: std::vec::Vec<PetscInt> = owned.iter().map(|&l| self.global[l]).collect();
        let owned_guess: std::vec::Vec<f64> = owned.iter().map(|&l| guess[l]).collect();
        let mut h = Handles::default();
        // SAFETY: every object is created here or in `new`, used with arrays
        // of the lengths PETSc expects, and destroyed with `h` or `self`.
        unsafe {
            self.assemble()?;
            h.b = self.vector(m, big, &self.global, rhs, ADD_VALUES)?;
            h.x = self.vector(m, big, &owned_rows, &owned_guess, INSERT_VALUES)?;
            check(KSPCreate(self.comm, &mut h.ksp), "KSPCreate")?;
            check(KSPSetOperators(h.ksp, self.aij, self.aij), "KSPSetOperators")?;
            check(KSPSetType(h.ksp, c_name("cg").as_ptr()), "KSPSetType")?;
            let mut pc: Pc = ptr::null_mut();
            check(KSPGetPC(h.ksp, &mut pc), "KSPGetPC")?;
            self.preconditioner(pc, &mut h)?;
            check(KSPSetTolerances(h.ksp, rtol, 1e-300, PETSC_DEFAULT as f64, 10_000), "KSPSetTolerances")?;
            check(KSPSetInitialGuessNonzero(h.ksp, PETSC_TRUE), "KSPSetInitialGuessNonzero")?;
            check(KSPSetFromOptions(h.ksp), "KSPSetFromOptions")?;
            check(KSPSolve(h.ksp, h.b, h.x), "KSPSolve")?;
            let (mut its, mut reason) = (0 as PetscInt, 0 as c_int);
            check(KSPGetIterationNumber(h.ksp, &mut its), "KSPGetIterationNumber")?;
            check(KSPGetConvergedReason(h.ksp, &mut reason), "KSPGetConvergedReason")?;
            if reason <= 0 {
                let mut s: *const c_char = ptr::null();
                KSPGetConvergedReasonString(h.ksp, &mut s);
                let why = if s.is_null() { format!("{reason}") } else { CStr::from_ptr(s).to_string_lossy().into() };
                return Err(format!("PETSc's CG did not converge in {its} iterations: {why}"));
            }
            Ok(Solved { iterations: its as usize, all: gather(&mut h)? })
        }
    }

    /// Assemble the local matrix and convert the unassembled one to `aij`.
    unsafe fn assemble(&mut self) -> Result<(), String> {
        check(MatAssemblyBegin(self.local, MAT_FINAL_ASSEMBLY), "MatAssemblyBegin")?;
        check(MatAssemblyEnd(self.local, MAT_FINAL_ASSEMBLY), "MatAssemblyEnd")?;
        check(MatAssemblyBegin(self.is, MAT_FINAL_ASSEMBLY), "MatAssemblyBegin")?;
        check(MatAssemblyEnd(self.is, MAT_FINAL_ASSEMBLY), "MatAssemblyEnd")?;
        let reuse = if self.aij.is_null() { MAT_INITIAL_MATRIX } else { MAT_REUSE_MATRIX };
        check(MatConvert(self.is, c_name("aij").as_ptr(), reuse, &mut self.aij), "MatConvert")
    }

    /// A distributed vector of `m` local and `big` global rows, block size
    /// d, zero but for `values` at the global `rows` (added or inserted).
    unsafe fn vector(
        &self,
        m: PetscInt,
        big: PetscInt,
        rows: &[PetscInt],
        values: &[f64],
        mode: c_int,
    ) -> Result<Vec, String> {
        let mut v: Vec = ptr::null_mut();
        check(VecCreateMPI(self.comm, m, big, &mut v), "VecCreateMPI")?;
        let filled = (|| {
            check(VecSetBlockSize(v, self.block as PetscInt), "VecSetBlockSize")?;
            check(VecSet(v, 0.0), "VecSet")?;
            check(VecSetValues(v, rows.len() as PetscInt, rows.as_ptr(), values.as_ptr(), mode), "VecSetValues")?;
            check(VecAssemblyBegin(v), "VecAssemblyBegin")?;
            check(VecAssemblyEnd(v), "VecAssemblyEnd")
        })();
        if let Err(e) = filled {
            VecDestroy(&mut v);
            return Err(e);
        }
        Ok(v)
    }

    /// The preconditioner `pc`: a two-level p-multigrid (Chebyshev on point
    /// blocks on the order-p level, one AMG V-cycle on the P1 level), or AMG
    /// on the matrix itself when there is no P1 level; AMG is given the
    /// rigid-body modes of its matrix from its owned nodes' coordinates.
    unsafe fn preconditioner(&mut self, pc: Pc, h: &mut Handles) -> Result<(), String> {
        let mut amg: Pc = pc;
        let (amg_matrix, (m, big), coords) = match &mut self.coarse {
            None => (self.aij, (self.n_owned, self.n_global), self.owned_coords.clone()),
            Some(c) => {
                let reuse = if c.ac.is_null() { MAT_INITIAL_MATRIX } else { MAT_REUSE_MATRIX };
                check(MatPtAP(self.aij, c.p, reuse, 2.0, &mut c.ac), "MatPtAP")?;
                check(PCSetType(pc, c_name("mg").as_ptr()), "PCSetType")?;
                check(PCMGSetLevels(pc, 2, ptr::null_mut()), "PCMGSetLevels")?;
                check(PCMGSetGalerkin(pc, PC_MG_GALERKIN_NONE), "PCMGSetGalerkin")?;
                check(PCMGSetInterpolation(pc, 1, c.p), "PCMGSetInterpolation")?;
                let (mut smoother, mut spc, mut coarse): (Ksp, Pc, Ksp) =
                    (ptr::null_mut(), ptr::null_mut(), ptr::null_mut());
                check(PCMGGetSmoother(pc, 1, &mut smoother), "PCMGGetSmoother")?;
                check(KSPSetOperators(smoother, self.aij, self.aij), "KSPSetOperators")?;
                check(KSPSetType(smoother, c_name("chebyshev").as_ptr()), "KSPSetType")?;
                check(KSPGetPC(smoother, &mut spc), "KSPGetPC")?;
                check(PCSetType(spc, c_name("pbjacobi").as_ptr()), "PCSetType")?;
                check(KSPSetTolerances(smoother, 0.0, 0.0, PETSC_DEFAULT as f64, 3), "KSPSetTolerances")?;
                check(PCMGGetCoarseSolve(pc, &mut coarse), "PCMGGetCoarseSolve")?;
                check(KSPSetOperators(coarse, c.ac, c.ac), "KSPSetOperators")?;
                check(KSPSetType(coarse, c_name("preonly").as_ptr()), "KSPSetType")?;
                check(KSPGetPC(coarse, &mut amg), "KSPGetPC")?;
                (c.ac, (c.n_owned, c.n_global), c.owned_coords.clone())
            }
        };
        check(PCSetType(amg, c_name("gamg").as_ptr()), "PCSetType")?;
        let (m, big) = (m as PetscInt, big as PetscInt);
        h.xyz = self.vector(m, big, &[], &[], INSERT_VALUES)?;
        let mut lo: PetscInt = 0;
        check(VecGetOwnershipRange(h.xyz, &mut lo, ptr::null_mut()), "VecGetOwnershipRange")?;
        let rows: std::vec::Vec<PetscInt> = (lo..lo + m).collect();
        check(VecSetValues(h.xyz, m, rows.as_ptr(), coords.as_ptr(), INSERT_VALUES), "VecSetValues")?;
        check(VecAssemblyBegin(h.xyz), "VecAssemblyBegin")?;
        check(VecAssemblyEnd(h.xyz), "VecAssemblyEnd")?;
        check(MatNullSpaceCreateRigidBody(h.xyz, &mut h.nsp), "MatNullSpaceCreateRigidBody")?;
        check(MatSetNearNullSpace(amg_matrix, h.nsp), "MatSetNearNullSpace")
    }
}

/// Every value of the solution `h.x`, on every process.
unsafe fn gather(h: &mut Handles) -> Result<std::vec::Vec<f64>, String> {
    check(VecScatterCreateToAll(h.x, &mut h.scatter, &mut h.all), "VecScatterCreateToAll")?;
    check(VecScatterBegin(h.scatter, h.x, h.all, INSERT_VALUES, SCATTER_FORWARD), "VecScatterBegin")?;
    check(VecScatterEnd(h.scatter, h.x, h.all, INSERT_VALUES, SCATTER_FORWARD), "VecScatterEnd")?;
    let mut n: PetscInt = 0;
    check(VecGetLocalSize(h.all, &mut n), "VecGetLocalSize")?;
    let mut a: *const f64 = ptr::null();
    check(VecGetArrayRead(h.all, &mut a), "VecGetArrayRead")?;
    let values = std::slice::from_raw_parts(a, n as usize).to_vec();
    check(VecRestoreArrayRead(h.all, &mut a), "VecRestoreArrayRead")?;
    Ok(values)
}

/// The objects of one solve, destroyed when it ends however it ends.
struct Handles {
    b: Vec,
    x: Vec,
    xyz: Vec,
    all: Vec,
    ksp: Ksp,
    scatter: VecScatter,
    nsp: MatNullSpace,
}

impl Default for Handles {
    fn default() -> Self {
        Handles {
            b: ptr::null_mut(),
            x: ptr::null_mut(),
            xyz: ptr::null_mut(),
            all: ptr::null_mut(),
            ksp: ptr::null_mut(),
            scatter: ptr::null_mut(),
            nsp: ptr::null_mut(),
        }
    }
}

impl Drop for Handles {
    fn drop(&mut self) {
        // SAFETY: destroying null handles is a no-op in PETSc.
        unsafe {
            KSPDestroy(&mut self.ksp);
            MatNullSpaceDestroy(&mut self.nsp);
            VecScatterDestroy(&mut self.scatter);
            for v in [&mut self.b, &mut self.x, &mut self.xyz, &mut self.all] {
                VecDestroy(v);
            }
        }
    }
}

impl Drop for PetscSystem {
    fn drop(&mut self) {
        // SAFETY: the handles were created by PETSc or are null.
        unsafe {
            if let Some(c) = &mut self.coarse {
                MatDestroy(&mut c.p);
                MatDestroy(&mut c.ac);
            }
            MatDestroy(&mut self.aij);
            MatDestroy(&mut self.is);
            MatDestroy(&mut self.local);
            ISLocalToGlobalMappingDestroy(&mut self.l2g);
        }
    }
}
