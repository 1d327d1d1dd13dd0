! distributed.c in Fortran, through the hocurve module: each MPI process
! gives its own share of a mesh (hoc_mesh_create_distributed) with its own
! projector, curves it with the others and writes what its handle holds.
!
!   mpirun -np N distributed_f DIR ORDER OPTIMIZE FAIL_RANK
!
! Same input (DIR/part.R.txt) and output (DIR/out.R.txt) as distributed.c.
module share_projector
  use, intrinsic :: iso_c_binding
  implicit none
  integer :: mesh_dim = 3, shape_tag = 0
  real(c_double) :: centre(3), radius
  logical :: failing = .false.
contains
  ! The circle or sphere of the share's file; FAIL_RANK's always fails.
  function project(user_data, entity_dim, entity_tag, n_points, points, projected) bind(C) result(status)
    type(c_ptr), value :: user_data
    integer(c_int), value :: entity_dim, entity_tag
    integer(c_size_t), value :: n_points
    real(c_double), intent(in) :: points(*)
    real(c_double), intent(out) :: projected(*)
    integer(c_int) :: status
    integer(c_size_t) :: i, k
    real(c_double) :: r
    status = 7
    if (failing) return
    status = 1
    if (entity_tag /= shape_tag .or. entity_dim < 0) return
    do i = 0, n_points - 1
      k = i * mesh_dim
      r = norm2(points(k + 1:k + mesh_dim) - centre(1:mesh_dim))
      projected(k + 1:k + mesh_dim) = centre(1:mesh_dim) + radius * (points(k + 1:k + mesh_dim) - centre(1:mesh_dim)) / r
    end do
    status = 0
  end function project
end module share_projector

program distributed_f
  use, intrinsic :: iso_c_binding
  use mpi
  use hocurve
  use share_projector
  implicit none
  integer :: provided, ierr, rank, order, optimize, fail_rank, nv, nc, nf, ns, i, j, u
  character(len=4096) :: dir, arg, path
  integer(c_int64_t), allocatable :: ids(:), cells(:, :), facets(:, :), global(:), conn(:, :)
  integer(c_int32_t), allocatable :: tags(:)
  integer(c_int), allocatable :: owner(:)
  real(c_double), allocatable :: coords(:, :), before(:, :), nodes(:, :), xyz(:, :)
  type(c_ptr) :: mesh
  type(hoc_quality) :: q
  integer(c_int) :: st
  integer(c_size_t) :: n_before, n_nodes, n_cells, npc
  character(len=:), allocatable :: message
  logical :: unchanged

  call MPI_Init_thread(MPI_THREAD_SERIALIZED, provided, ierr)
  call MPI_Comm_rank(MPI_COMM_WORLD, rank, ierr)
  call get_command_argument(1, dir)
  call get_command_argument(2, arg); read (arg, *) order
  call get_command_argument(3, arg); read (arg, *) optimize
  call get_command_argument(4, arg); read (arg, *) fail_rank
  write (path, '(a,"/part.",i0,".txt")') trim(dir), rank
  open (newunit=u, file=trim(path), status='old', action='read')
  read (u, *) mesh_dim, nv, nc, nf, ns
  allocate (ids(nv), coords(mesh_dim, nv), cells(mesh_dim + 1, nc), facets(mesh_dim, nf), tags(nf))
  do i = 1, nv
    read (u, *) ids(i), coords(:, i)
  end do
  read (u, *) cells
  do i = 1, nf
    read (u, *) facets(:, i), tags(i)
  end do
  read (u, *) shape_tag, centre, radius
  close (u)
  failing = rank == fail_rank

  st = hoc_mesh_create_distributed(MPI_COMM_WORLD, mesh_dim, int(nv, c_size_t), coords, ids, &
                                   int(nc, c_size_t), cells, mesh)
  if (st /= HOC_OK) call fail('create')
  if (hoc_mesh_set_boundary(mesh, int(nf, c_size_t), facets, tags) /= HOC_OK) call fail('boundary')
  if (hoc_mesh_set_projector(mesh, c_funloc(project), c_null_ptr) /= HOC_OK) call fail('projector')
  if (hoc_mesh_set_order(mesh, order, HOC_SPACING_OPTIMAL) /= HOC_OK) call fail('order')
  if (hoc_mesh_set_optimize(mesh, optimize) /= HOC_OK) call fail('optimize')
  st = hoc_mesh_node_count(mesh, n_before)
  allocate (before(mesh_dim, n_before))
  st = hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_before, before)

  st = hoc_mesh_run_increments(mesh, HOC_DEFAULT_INCREMENTS)
  message = hoc_string(hoc_mesh_last_error(mesh))

  if (hoc_mesh_node_count(mesh, n_nodes) /= HOC_OK) call fail('node count')
  if (hoc_mesh_cell_count(mesh, n_cells, npc) /= HOC_OK) call fail('cell count')
  allocate (nodes(mesh_dim, n_nodes))
  if (hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, nodes) /= HOC_OK) call fail('nodes')
  unchanged = n_nodes == n_before
  if (unchanged) unchanged = all(nodes == before)

  write (path, '(a,"/out.",i0,".txt")') trim(dir), rank
  open (newunit=u, file=trim(path), status='replace', action='write')
  write (u, '(i0)') st
  write (u, '(a)') message
  write (u, '(i0)') merge(1, 0, unchanged)
  if (st == HOC_OK) then
    if (hoc_mesh_quality(mesh, q) /= HOC_OK) call fail('quality')
    write (u, '(*(g0,1x))') n_nodes, n_cells, npc, q%min_q3, q%n_invalid, q%n_certified_invalid
    allocate (global(n_nodes), owner(n_nodes), conn(npc, n_cells), xyz(mesh_dim, n_nodes))
    if (hoc_mesh_get_global_nodes(mesh, n_nodes, global, owner) /= HOC_OK) call fail('global nodes')
    if (hoc_mesh_get_cells(mesh, HOC_ORDERING_GMSH, n_cells * npc, conn) /= HOC_OK) call fail('cells')
    if (hoc_mesh_get_nodes(mesh, HOC_ORDERING_GMSH, n_nodes, xyz) /= HOC_OK) call fail('gmsh nodes')
    do i = 1, int(n_nodes)
      write (u, '(*(g0,1x))') global(i), owner(i), nodes(:, i)
    end do
    do i = 1, int(n_cells)
      ! The share's own vertices are its first nodes, in the order it gave them.
      write (u, '(*(g0,1x))') (merge(ids(min(conn(j, i) + 1, int(nv, c_int64_t))), -1_c_int64_t, conn(j, i) < nv), &
                               j = 1, mesh_dim + 1), (xyz(:, conn(j, i) + 1), j = 1, int(npc))
    end do
  end if
  close (u)
  st = hoc_mesh_destroy(mesh)
  call MPI_Finalize(ierr)

contains
  subroutine fail(what)
    character(len=*), intent(in) :: what
    write (0, '("rank ",i0,": ",a,": ",a)') rank, what, hoc_string(hoc_mesh_last_error(mesh))
    call MPI_Abort(MPI_COMM_WORLD, 1, ierr)
  end subroutine fail
end program distributed_f
