! The Fortran module end to end: an annulus 1 < r < 2 of straight triangles,
! curved at p = 4 with a projector written in Fortran (bind(C), passed with
! c_funloc). Every boundary node ends on its circle: the inner and outer
! circles each carry n_theta*p nodes to 1e-10 (only the n_theta vertices before).
module circle_projector
  use, intrinsic :: iso_c_binding
  use hocurve
  implicit none
contains
  function project_circle(user_data, entity_dim, entity_tag, n_points, points, projected) &
      bind(C) result(status)
    type(c_ptr), value :: user_data
    integer(c_int), value :: entity_dim, entity_tag
    integer(c_size_t), value :: n_points
    real(c_double), intent(in) :: points(*)
    real(c_double), intent(out) :: projected(*)
    integer(c_int) :: status
    integer(c_size_t) :: i
    real(c_double) :: r, radius
    integer, pointer :: calls
    if (c_associated(user_data)) then
      call c_f_pointer(user_data, calls)
      calls = calls + 1
    end if
    status = 1
    if (entity_dim /= 1) return
    select case (entity_tag)
    case (1)
      radius = 1.0_c_double
    case (2)
      radius = 2.0_c_double
    case default
      return
    end select
    do i = 0, n_points - 1
      r = hypot(points(2*i + 1), points(2*i + 2))
      projected(2*i + 1) = points(2*i + 1) * radius / r
      projected(2*i + 2) = points(2*i + 2) * radius / r
    end do
    status = 0
  end function project_circle
end module circle_projector

program t401_curve_f
  use, intrinsic :: iso_c_binding
  use hocurve
  use circle_projector
  implicit none
  integer, parameter :: nt = 16, nr = 3, p = 4
  real(c_double), parameter :: pi = 3.14159265358979323846_c_double
  real(c_double) :: coords(2, nt*(nr + 1))
  integer(c_int64_t) :: cells(3, 2*nt*nr), facets(2, 2*nt)
  integer(c_int32_t) :: tags(2*nt)
  real(c_double), allocatable :: x(:, :)
  type(c_ptr) :: mesh
  type(hoc_quality) :: q
  type(hoc_timings) :: tm
  integer(c_size_t) :: n_nodes, n_cells, npc
  integer(c_int) :: st
  integer, target :: calls
  integer :: i, j, c, f, a, b, on_inner, on_outer
  integer(c_int) :: caps_kept
  integer(c_size_t) :: message_len
  character(kind=c_char) :: message(64)

  do i = 0, nr
    do j = 0, nt - 1
      coords(1, i*nt + j + 1) = (1.0_c_double + real(i, c_double)/nr) * cos(2*pi*j/nt)
      coords(2, i*nt + j + 1) = (1.0_c_double + real(i, c_double)/nr) * sin(2*pi*j/nt)
    end do
  end do
  c = 0
  do i = 0, nr - 1
    do j = 0, nt - 1
      a = i*nt + j
      b = i*nt + mod(j + 1, nt)
      c = c + 1
      cells(:, c) = [int(a, c_int64_t), int(b, c_int64_t), int(b + nt, c_int64_t)]
      c = c + 1
      cells(:, c) = [int(a, c_int64_t), int(b + nt, c_int64_t), int(a + nt, c_int64_t)]
    end do
  end do
  f = 0
  do j = 0, nt - 1
    f = f + 1
    facets(:, f) = [int(j, c_int64_t), int(mod(j + 1, nt), c_int64_t)]
    tags(f) = 1
    f = f + 1
    facets(:, f) = [int(nr*nt + j, c_int64_t), int(nr*nt + mod(j + 1, nt), c_int64_t)]
    tags(f) = 2
  end do

  call check(hoc_mesh_create(2_c_int, int(size(coords, 2), c_size_t), coords, &
                             int(size(cells, 2), c_size_t), cells, mesh), "create")
  call check(hoc_mesh_set_boundary(mesh, int(size(tags), c_size_t), facets, tags), "set_boundary")
  calls = 0
  call check(hoc_mesh_set_projector(mesh, c_funloc(project_circle), c_loc(calls)), "set_projector")
  call check(hoc_mesh_set_material(mesh, HOC_MATERIAL_LINEAR_ELASTIC, 1.0_c_double, 0.3_c_double), &
             "set_material")
  call check(hoc_mesh_set_formulation(mesh, HOC_FORMULATION_LINEAR), "set_formulation")
  call check(hoc_mesh_set_newton(mesh, 1.0e-6_c_double, 20_c_int), "set_newton")
  call check(hoc_mesh_set_fibres(mesh, 0_c_size_t, c_null_ptr), "set_fibres")
  st = hoc_mesh_set_newton(mesh, 1.0e-6_c_double, -1_c_int)
  if (st /= HOC_ERROR_INVALID_ARGUMENT .or. len(hoc_string(hoc_mesh_last_error(mesh))) == 0) then
    print *, "set_newton(1e-6, -1) gave", st
    error stop 1
  end if

  ! A bad order: a status and a message, read through hoc_string.
  st = hoc_mesh_set_order(mesh, 11_c_int, HOC_SPACING_OPTIMAL)
  if (st /= HOC_ERROR_INVALID_ARGUMENT .or. len(hoc_string(hoc_mesh_last_error(mesh))) == 0) then
    print *, "order 11 gave", st
    error stop 1
  end if
  print '(a, a, a, a)', "order 11: ", hoc_string(hoc_status_string(st)), ": ", &
    hoc_string(hoc_mesh_last_error(mesh))

  call check(hoc_mesh_set_order(mesh, int(p, c_int), HOC_SPACING_OPTIMAL), "set_order")
  call check(hoc_mesh_node_count(mesh, n_nodes), "node_count")
  call check(hoc_mesh_cell_count(mesh, n_cells, npc), "cell_count")
  if (npc /= (p + 1)*(p + 2)/2 .or. n_cells /= size(cells, 2)) error stop "cell_count"
  allocate (x(2, n_nodes))
  call check(hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, x), "get_nodes")
  call count_on_circles(x, on_inner, on_outer)
  if (on_inner /= nt .or. on_outer /= nt) then
    print *, "straight mesh: nodes on circles", on_inner, on_outer
    error stop 1
  end if

  call check(hoc_mesh_set_retry(mesh, 1_c_int), "set_retry")
  call check(hoc_mesh_set_tangent_first(mesh, 0_c_int), "set_tangent_first")
  call check(hoc_mesh_run_increments(mesh, 1_c_int), "run_increments")
  call check(hoc_mesh_quality(mesh, q), "quality")
  call check(hoc_mesh_timings(mesh, tm), "timings")
  if (tm%total <= 0 .or. tm%solve <= 0 .or. tm%solve > tm%total) then
    print *, "timings: total", tm%total, " solve", tm%solve
    error stop 1
  end if
  ! A 2D mesh has no caps: the run is made once.
  call check(hoc_mesh_retry(mesh, caps_kept, message_len, int(size(message), c_size_t), message), "retry")
  if (caps_kept /= 0 .or. message_len /= 0 .or. message(1) /= c_null_char) then
    print *, "retry: caps_kept", caps_kept, " message_len", message_len
    error stop 1
  end if
  call check(hoc_mesh_get_nodes(mesh, HOC_ORDERING_NATIVE, n_nodes, x), "get_nodes")
  call count_on_circles(x, on_inner, on_outer)
  if (q%n_invalid /= 0 .or. q%min_q3 <= 0) then
    print *, "invalid cells:", q%n_invalid, " min Q3", q%min_q3
    error stop 1
  end if
  if (on_inner /= nt*p .or. on_outer /= nt*p) then
    print *, "curved mesh: nodes on circles", on_inner, on_outer, " expected", nt*p
    error stop 1
  end if
  if (calls == 0) error stop "projector never called"
  print '(a, a, a, i0, a, i0, a, i0, a, f6.3, a, i0, a)', "hocurve ", hoc_string(hoc_version()), &
    " via Fortran: p=", p, ", ", on_inner, " + ", on_outer, " nodes on the circles, min Q3 ", &
    q%min_q3, ", ", calls, " projector calls"
  deallocate (x)
  call check(hoc_mesh_destroy(mesh), "destroy")
  if (c_associated(mesh)) error stop "destroy did not clear the handle"

contains

  subroutine check(status, what)
    integer(c_int), intent(in) :: status
    character(*), intent(in) :: what
    if (status /= HOC_OK) then
      print '(a, a, i0, a, a)', what, ": status ", status, ": ", hoc_string(hoc_mesh_last_error(mesh))
      error stop 1
    end if
  end subroutine check

  subroutine count_on_circles(x, inner, outer)
    real(c_double), intent(in) :: x(:, :)
    integer, intent(out) :: inner, outer
    integer :: k
    real(c_double) :: r
    inner = 0
    outer = 0
    do k = 1, size(x, 2)
      r = hypot(x(1, k), x(2, k))
      if (abs(r - 1) < 1e-10_c_double) inner = inner + 1
      if (abs(r - 2) < 1e-10_c_double) outer = outer + 1
    end do
  end subroutine count_on_circles

end program t401_curve_f
