# PETSc over MPI for the distributed FEM backend (sim/petsc/, docs/solver.md#petsc-more-than-one-machine). Optional:
# found through pkg-config (Debian's petsc-dev puts PETSc.pc under /usr/lib/petscdir/...); when
# absent everything builds as before and asking for the backend is a one-line error.
option(INCISE_WITH_PETSC "Build the PETSc/MPI solver backend when PETSc and MPI are found" ON)
set(INCISE_HAVE_PETSC OFF)
if(INCISE_WITH_PETSC)
  find_package(PkgConfig QUIET)
  set(MPI_CXX_SKIP_MPICXX ON)  # the C API only; the project enables no C compiler
  find_package(MPI QUIET COMPONENTS CXX)
  if(PkgConfig_FOUND)
    pkg_check_modules(PETSC QUIET IMPORTED_TARGET PETSc)
  endif()
  if(PETSC_FOUND AND MPI_CXX_FOUND)
    set(INCISE_HAVE_PETSC ON)
    message(STATUS "PETSc ${PETSC_VERSION}: the petsc solver backend is on")
  else()
    message(STATUS "PETSc or MPI not found: the petsc solver backend is off (petsc-dev, openmpi-bin)")
  endif()
endif()
