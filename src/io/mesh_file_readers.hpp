#pragma once
// Internal: the format readers behind read_mesh_file() (include/modalcal/mesh_file.hpp) and the
// checks they share.
#include <string>
#include <vector>

#include "modalcal/mesh_file.hpp"

namespace modalcal::detail {

/// A mesh as a reader finds it: every node of the file, in the reader's order, with blocks,
/// node sets and side sets indexing them. read_mesh_file() checks and compacts it.
struct RawMesh {
  std::vector<Vec3> coordinates;
  std::vector<long> node_ids;
  std::vector<MeshFileBlock> blocks;
  std::vector<MeshFileNodeSet> node_sets;  ///< nodes sorted and unique
  std::vector<MeshFileSideSet> side_sets;
  std::vector<std::string> warnings;
};

/// Throws ProblemError(path, 0, message): mesh files have no line a library would tell.
[[noreturn]] void mesh_error(const std::string& path, const std::string& message);

/// Throws mesh_error unless `path` is an existing regular file.
void require_regular_file(const std::string& path);

/// Reads a .msh file through the Gmsh library (one call at a time: Gmsh's state is global).
RawMesh read_gmsh(const std::string& path);

/// Reads an Exodus II file through the Exodus II library.
RawMesh read_exodus(const std::string& path);

}  // namespace modalcal::detail
