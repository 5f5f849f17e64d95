// Gmsh meshes: read_mesh_file() on an input named .msh (our header check, then the Gmsh library,
// then the checks every mesh passes).
//
// Only ASCII MSH 2 inputs ("$MeshFormat" then a version 2.x, file type 0) reach Gmsh here; the
// rest go no further than our own check of the first line. Gmsh 4.8's MSH 4 reader crashes on
// malformed files within seconds of fuzzing (fuzz/known-crashes/gmsh/: a bad free in
// GModel::_readMSH4, a free of memory it never allocated in GEO_Internals::_freeAll from
// ~GModel, std::terminate on a std::length_error thrown inside _readMSH4; stacks in
// docs/fuzzing.md), and checking an MSH 4 file before Gmsh reads it would take a second MSH 4
// parser. Its MSH 2 reader crashed on an element naming an undefined node; the reader now checks
// the $Nodes and $Elements lines of an ASCII MSH 2 file first (fuzz/regressions/gmsh/).
#include <cstring>
#include <string>

#include "fuzz_input.hpp"
#include "modalcal/mesh_file.hpp"

namespace {

// "$MeshFormat", a line end, then "2" or "2.<digits>", blanks and "0" (ASCII).
bool is_ascii_msh2(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), std::min<size_t>(size, 64));
  const size_t version = text.find('\n');
  if (text.rfind("$MeshFormat", 0) != 0 || version == std::string::npos) return true;  // our check refuses it
  size_t i = version + 1;
  if (i >= text.size() || text[i] != '2') return false;
  for (++i; i < text.size() && (text[i] == '.' || (text[i] >= '0' && text[i] <= '9')); ++i) {
  }
  while (i < text.size() && (text[i] == ' ' || text[i] == '\t')) ++i;
  return i + 1 < text.size() && text[i] == '0' && (text[i + 1] == ' ' || text[i + 1] == '\t');
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (!is_ascii_msh2(data, size)) return 0;
  return modalcal::fuzz::read_as_file(data, size, "input.msh",
                                      [](const std::string& path) { (void)modalcal::read_mesh_file(path); });
}
