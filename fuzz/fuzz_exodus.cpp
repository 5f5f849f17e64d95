// Exodus II meshes: read_mesh_file() on an input named .exo (the Exodus II library, then the
// checks every mesh passes).
//
// Only netCDF classic inputs (starting "CDF": the 32-bit, 64-bit-offset and 64-bit-data layouts)
// reach the Exodus library here. Exodus files in the netCDF-4 layout are HDF5 files, and Debian's
// HDF5 1.10 crashes on malformed ones at once (a SEGV freeing a link table in
// H5G__link_release_table; fuzz/known-crashes/exodus/, stack in docs/fuzzing.md): such a file
// cannot be checked before HDF5 reads it without an HDF5 parser of our own. netCDF's classic
// reader hung on a header count off by a byte; the reader now walks a classic header first
// (fuzz/regressions/exodus/). Any other input netCDF refuses as "not a netCDF file" unparsed.
#include "fuzz_input.hpp"
#include "modalcal/mesh_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 4 || data[0] != 'C' || data[1] != 'D' || data[2] != 'F') return 0;
  return modalcal::fuzz::read_as_file(data, size, "input.exo",
                                      [](const std::string& path) { (void)modalcal::read_mesh_file(path); });
}
