# Finds CHOLMOD from SuiteSparse (Debian: libsuitesparse-dev) and defines Cholmod::Cholmod.
find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse)
find_library(CHOLMOD_LIBRARY cholmod)
find_library(SUITESPARSECONFIG_LIBRARY suitesparseconfig)
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(Cholmod DEFAULT_MSG CHOLMOD_LIBRARY CHOLMOD_INCLUDE_DIR SUITESPARSECONFIG_LIBRARY)
if(Cholmod_FOUND AND NOT TARGET Cholmod::Cholmod)
  add_library(Cholmod::Cholmod UNKNOWN IMPORTED)
  set_target_properties(Cholmod::Cholmod PROPERTIES
    IMPORTED_LOCATION "${CHOLMOD_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${CHOLMOD_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES "${SUITESPARSECONFIG_LIBRARY}")
endif()
# Debian's CHOLMOD runs OpenMP regions of its own; src/eigen/cholmod_factor.cpp keeps them in the
# calling thread, which needs the OpenMP runtime's omp_set_max_active_levels (not -fopenmp).
find_package(OpenMP COMPONENTS C)
if(Cholmod_FOUND AND OpenMP_C_FOUND)
  set_property(TARGET Cholmod::Cholmod APPEND PROPERTY INTERFACE_LINK_LIBRARIES ${OpenMP_C_LIBRARIES})
  set_property(TARGET Cholmod::Cholmod APPEND PROPERTY INTERFACE_COMPILE_DEFINITIONS MODALCAL_CHOLMOD_OPENMP)
endif()
