# Finds the Exodus II C library (Debian: libexodusii-dev, from SEACAS; it links netCDF itself)
# and defines ExodusII::ExodusII. Reads Exodus II meshes (src/io/exodus_reader.cpp).
find_path(EXODUSII_INCLUDE_DIR exodusII.h)
find_library(EXODUSII_LIBRARY NAMES exoIIv2c exodus)
# exodusII.h includes netcdf.h, which may live in its own folder.
find_path(NETCDF_INCLUDE_DIR netcdf.h PATH_SUFFIXES netcdf)
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(ExodusII DEFAULT_MSG EXODUSII_LIBRARY EXODUSII_INCLUDE_DIR NETCDF_INCLUDE_DIR)
if(ExodusII_FOUND AND NOT TARGET ExodusII::ExodusII)
  add_library(ExodusII::ExodusII UNKNOWN IMPORTED)
  set_target_properties(ExodusII::ExodusII PROPERTIES
    IMPORTED_LOCATION "${EXODUSII_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${EXODUSII_INCLUDE_DIR};${NETCDF_INCLUDE_DIR}")
endif()
