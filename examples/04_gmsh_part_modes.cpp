// Example 4: the modes of a part meshed by Gmsh.
//
// Shows: reading a mesh made by another program (a Gmsh .msh file: physical volumes become
// element blocks, physical surfaces node sets; Exodus II files work the same way), the problem
// file that gives it materials and supports by those names, the modal solve, and writing the
// modes for ParaView.
//
// Run:   build/bin/example_04_gmsh_part_modes [problem.yaml mesh-file]
//        (default: problems/bracket/bracket.yaml, an aluminium L-bracket bolted through two
//        holes, and its mesh bracket.msh, which Gmsh made from bracket.geo; the VTU files go to
//        a temporary folder; under a second)

#include <cstdio>
#include <filesystem>
#include <string>

#include "modalcal/assembly.hpp"
#include "modalcal/eigen.hpp"
#include "modalcal/mesh_file.hpp"
#include "modalcal/mode_description.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/vtu.hpp"
#include "modalcal/problem_file.hpp"

int main(int argc, char** argv) {
  using namespace modalcal;
  const std::string source = MODALCAL_SOURCE_DIR;
  const std::string path = argc > 2 ? argv[1] : source + "/problems/bracket/bracket.yaml";
  const std::string mesh_path = argc > 2 ? argv[2] : source + "/problems/bracket/bracket.msh";
  const std::string vtu_folder = (std::filesystem::temp_directory_path() / "modalcal_example_04").string();

  // 1. What the mesh file holds. A problem file names it as `mesh: {file: bracket.msh}`; here we
  //    read it directly to see its blocks and node sets (errors name the file and the fault).
  const MeshFile mesh = read_mesh_file(mesh_path);
  std::printf("%s (%s): %d nodes\n", mesh.path.c_str(), to_string(mesh.format).c_str(), mesh.num_nodes());
  for (const MeshFileBlock& b : mesh.blocks)
    std::printf("  block %-12s %5d %s elements\n", b.name.c_str(), b.num_elements(), solid_type_name(b.type).c_str());
  for (const MeshFileNodeSet& s : mesh.node_sets)
    std::printf("  node set %-12s %5zu nodes (%s)\n", s.name.c_str(), s.nodes.size(), s.source.c_str());

  // 2. The problem gives the mesh's blocks materials by name and puts the bolts, springs to
  //    ground, on the node sets of the hole walls; everything else in it works as for the box
  //    mesher's meshes. Node ids are the mesh file's.
  const Problem problem = load_problem(path);
  for (const std::string& warning : problem.warnings) std::printf("warning: %s\n", warning.c_str());

  // 3. Assemble at the file's parameter values and solve for the lowest modes.
  ParametricSystem system(problem.model, problem.parameter_targets());
  const Vector p = problem.initial_values();
  SparseMatrix K, M;
  system.assemble(p, &K, &M);
  ModalOptions options;
  options.num_modes = 6;
  options.max_rigid_modes = problem.expected_rigid_modes();
  ModalSolver solver(system.pattern(), options);
  const ModalResult result = solver.solve(K, M);
  if (result.status != EigenStatus::Successful) {
    std::fprintf(stderr, "modal solve failed: %s\n", result.message.c_str());
    return 1;
  }

  // 4. Describe them: which way each mode moves.
  std::printf("%d DOFs, %d elements\n", system.num_dofs(), problem.model.num_elements());
  for (const ModeDescription& d : describe_modes(system, p, M, result))
    std::printf("mode %d  %8.1f Hz  KE x/y/z %.2f %.2f %.2f\n", d.index, d.frequency_hz, d.energy_fraction[0],
                d.energy_fraction[1], d.energy_fraction[2]);

  // 5. Write the mesh with its blocks and the mode shapes for ParaView (open the .pvd file).
  VtuFields fields;
  add_mode_fields(result, -1, &fields);
  for (const std::string& file : write_vtu_set(vtu_folder, "modes", problem, system, p, fields))
    std::printf("wrote %s\n", file.c_str());
  return 0;
}
