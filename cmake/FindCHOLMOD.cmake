# Finds CHOLMOD (SuiteSparse 5.x from Debian ships no CMake or pkg-config files).
# Defines the imported target CHOLMOD::CHOLMOD.
#
# MOSLAM_STATIC_CHOLMOD (default ON): link CHOLMOD, the SuiteSparse orderings it calls and BLAS /
# LAPACK from their static archives (Debian's -dev packages ship them) instead of as ten shared
# libraries: the pose-graph commands start in milliseconds, and every shared library costs the
# dynamic loader part of one. BLAS / LAPACK: OpenBLAS (libopenblas-pthread-dev: its kernels make
# whole solves of sphere2500 and torus3D 30-40 % faster than ATLAS's generic build; the serial
# flavour is not used: Debian builds it without USE_LOCKING, and robots solving in threads of
# one process then corrupt each other's factorizations), else ATLAS (libatlas-base-dev). Our
# executables run OpenBLAS on one thread (apps/cli.h). METIS and OpenMP stay shared (no archives). Off, or without the archives:
# shared libraries, whatever BLAS the system selects.
# Static CHOLMOD leaves its OpenMP runtime to the executable: the serial one of
# src/moslam/solver/serial_openmp.cc, or libgomp (OpenMP::OpenMP_CXX).
option(MOSLAM_STATIC_CHOLMOD "Link CHOLMOD and ATLAS statically (faster start-up)" ON)

find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse)
find_library(CHOLMOD_LIBRARY cholmod)
find_library(SUITESPARSECONFIG_LIBRARY suitesparseconfig)

set(_cholmod_static_libs)
if(MOSLAM_STATIC_CHOLMOD)
  set(_cholmod_static_ok TRUE)
  # Link order: a library before those it calls.
  foreach(_name cholmod amd camd colamd ccolamd suitesparseconfig)
    find_library(_lib_${_name} NAMES lib${_name}.a)
    if(_lib_${_name})
      list(APPEND _cholmod_static_libs ${_lib_${_name}})
    else()
      set(_cholmod_static_ok FALSE)
    endif()
  endforeach()
  find_library(_lib_metis NAMES metis libmetis.so.5)  # shared only (no -dev link)
  set(_blas_dirs /usr/lib/x86_64-linux-gnu /usr/lib /usr/lib64)
  find_library(_lib_openblas NAMES libopenblas.a NO_DEFAULT_PATH
    PATHS ${_blas_dirs} PATH_SUFFIXES openblas-pthread)
  find_library(_lib_atlas_lapack NAMES liblapack.a NO_DEFAULT_PATH
    PATHS ${_blas_dirs} PATH_SUFFIXES atlas)
  find_library(_lib_atlas_blas NAMES libblas.a NO_DEFAULT_PATH
    PATHS ${_blas_dirs} PATH_SUFFIXES atlas)
  find_library(_lib_atlas NAMES libatlas.a)
  find_library(_lib_gfortran NAMES gfortran libgfortran.so.5)
  find_package(Threads REQUIRED)
  if(_lib_openblas)
    set(_blas_libs ${_lib_openblas} ${_lib_gfortran} Threads::Threads)
    set(_blas_name "OpenBLAS ${_lib_openblas}")
  elseif(_lib_atlas_lapack AND _lib_atlas_blas AND _lib_atlas)
    set(_blas_libs ${_lib_atlas_lapack} ${_lib_atlas_blas} ${_lib_atlas} ${_lib_gfortran})
    set(_blas_name "ATLAS ${_lib_atlas_blas}")
  else()
    set(_cholmod_static_ok FALSE)
  endif()
  if(NOT _lib_metis OR NOT _lib_gfortran)
    set(_cholmod_static_ok FALSE)
  endif()
  if(_cholmod_static_ok)
    list(APPEND _cholmod_static_libs ${_lib_metis} ${_blas_libs} m)
  else()
    message(STATUS "CHOLMOD: static archives (SuiteSparse, BLAS) not all found: linking shared")
    set(_cholmod_static_libs)
  endif()
endif()

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(CHOLMOD
  REQUIRED_VARS CHOLMOD_LIBRARY SUITESPARSECONFIG_LIBRARY CHOLMOD_INCLUDE_DIR)
if(CHOLMOD_FOUND AND NOT TARGET CHOLMOD::CHOLMOD)
  if(_cholmod_static_libs)
    add_library(CHOLMOD::CHOLMOD INTERFACE IMPORTED)
    set_target_properties(CHOLMOD::CHOLMOD PROPERTIES
      INTERFACE_INCLUDE_DIRECTORIES "${CHOLMOD_INCLUDE_DIR}"
      INTERFACE_LINK_LIBRARIES "${_cholmod_static_libs}")
    message(STATUS "CHOLMOD: static (${_lib_cholmod}, ${_blas_name})")
  else()
    add_library(CHOLMOD::CHOLMOD UNKNOWN IMPORTED)
    set_target_properties(CHOLMOD::CHOLMOD PROPERTIES
      IMPORTED_LOCATION "${CHOLMOD_LIBRARY}"
      INTERFACE_INCLUDE_DIRECTORIES "${CHOLMOD_INCLUDE_DIR}"
      INTERFACE_LINK_LIBRARIES "${SUITESPARSECONFIG_LIBRARY}")
  endif()
endif()
mark_as_advanced(CHOLMOD_INCLUDE_DIR CHOLMOD_LIBRARY SUITESPARSECONFIG_LIBRARY)
