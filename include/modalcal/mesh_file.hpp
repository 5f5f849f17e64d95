#pragma once
/// \file mesh_file.hpp
/// Solid meshes made by other programs: Gmsh `.msh` files (read by the Gmsh library) and
/// Exodus II files (read by the Exodus II library, the format of Sierra-SD and Cubit).
///
/// What is taken (details in docs/problem-format.md, "Meshes from files"):
/// - **Gmsh**: each physical volume group becomes an element block named after the group;
///   each physical surface, curve or point group becomes a node set of the nodes of its
///   elements. Elements outside every physical volume group are left out (with a warning).
/// - **Exodus II**: element blocks, node sets, and side sets (as element sides, and as the node
///   set of the nodes on those sides), named by the file's names.
///
/// Supported elements: hex8, tet4 and tet10. Connectivity is converted to the node order of
/// elements.hpp (Exodus order; Gmsh's 10-node tetrahedron has its last two mid-edge nodes the
/// other way round). Nodes no supported element uses are dropped, the rest keep the file's ids.
/// Every element is checked for a positive Jacobian determinant.
///
/// \code
/// modalcal::MeshFile mesh = modalcal::read_mesh_file("problems/bracket/bracket.msh");
/// for (const modalcal::MeshFileBlock& b : mesh.blocks)
///   std::cout << b.name << ": " << b.num_elements() << " " << modalcal::solid_type_name(b.type) << "\n";
/// \endcode

#include <optional>
#include <string>
#include <vector>

#include "modalcal/elements.hpp"
#include "modalcal/export.hpp"
#include "modalcal/types.hpp"

namespace modalcal {

enum class MeshFileFormat { Gmsh, Exodus };

/// "gmsh" or "exodus".
MODALCAL_EXPORT std::string to_string(MeshFileFormat format);

/// The format a file name's extension stands for: `.msh` → Gmsh; `.exo`, `.e`, `.g`, `.gen`,
/// `.exoII`, `.ex2` → Exodus II (case-insensitive); anything else: none.
MODALCAL_EXPORT std::optional<MeshFileFormat> mesh_format_from_extension(const std::string& path);

/// Elements of one type under one name: a Gmsh physical volume group or an Exodus element block.
struct MODALCAL_EXPORT MeshFileBlock {
  std::string name;    ///< the group's or block's name; unnamed: "volume_<tag>" (Gmsh), "block_<id>" (Exodus)
  long id = 0;         ///< the physical tag (Gmsh) or block id (Exodus)
  SolidType type = SolidType::Hex8;
  std::vector<int> connectivity;  ///< indices into MeshFile::coordinates, nodes_per_element(type) per element, elements.hpp order
  std::vector<long> element_ids;  ///< the file's element tags (Gmsh) or element numbers (Exodus), one per element
  int num_elements() const { return static_cast<int>(element_ids.size()); }
};

/// Named nodes: a Gmsh physical surface, curve or point group, an Exodus node set, or the nodes
/// on an Exodus side set's sides.
struct MODALCAL_EXPORT MeshFileNodeSet {
  std::string name;    ///< unnamed: "surface_<tag>", "curve_<tag>", "point_<tag>" (Gmsh), "nodeset_<id>", "sideset_<id>" (Exodus)
  std::string source;  ///< what it came from, for messages, e.g. "physical surface 2" or "side set 3"
  std::vector<int> nodes;  ///< indices into MeshFile::coordinates, sorted, unique
};

/// An Exodus side set as element sides (its nodes are also a MeshFile node set of the same name).
struct MODALCAL_EXPORT MeshFileSideSet {
  std::string name;  ///< unnamed: "sideset_<id>"
  long id = 0;
  std::vector<long> elements;  ///< the file's element numbers (1-based, over all blocks in file order)
  std::vector<int> sides;      ///< 1-based Exodus side numbers (solid_side_nodes()), one per element
};

struct MODALCAL_EXPORT MeshFile {
  std::string path;
  MeshFileFormat format = MeshFileFormat::Gmsh;
  std::vector<Vec3> coordinates;  ///< nodes used by the blocks' elements
  std::vector<long> node_ids;     ///< the file's node tags (Gmsh) or node number map (Exodus)
  std::vector<MeshFileBlock> blocks;
  std::vector<MeshFileNodeSet> node_sets;  ///< names unique
  std::vector<MeshFileSideSet> side_sets;  ///< Exodus only
  /// What reading left out or found odd, e.g. elements in no physical volume group, nodes of a
  /// node set that no element uses.
  std::vector<std::string> warnings;

  int num_nodes() const { return static_cast<int>(coordinates.size()); }
  const MeshFileBlock* find_block(const std::string& name) const;
  const MeshFileNodeSet* find_node_set(const std::string& name) const;
};

/// Reads a Gmsh or Exodus II mesh; `format` defaults to mesh_format_from_extension(path).
/// For a Gmsh file the Gmsh API is initialized and finalized around the read (its state is
/// global; concurrent reads wait for each other), so do not call it while the program holds a
/// Gmsh session of its own.
/// \throws ProblemError (problem.hpp) with the mesh file's path and what is wrong: no such
///         file, unknown extension without `format`, not a mesh of that format, the reading
///         library's own error (truncated or malformed file), a 2-D mesh, an unsupported element
///         type (named, with the supported ones), a physical group or block mixing element types
///         or an element in two physical volume groups, no physical volume group, duplicate
///         names, an inverted or degenerate element (file element id and block named).
MODALCAL_EXPORT MeshFile read_mesh_file(const std::string& path, std::optional<MeshFileFormat> format = std::nullopt);

}  // namespace modalcal
