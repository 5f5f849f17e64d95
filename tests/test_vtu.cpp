// VTU output: the document's structure, that bad fields are refused before anything is written,
// that writes are atomic and never replace an input. (Reading the files back with VTK's own
// reader is the ctest VtuReadBack.Vtk, tests/vtu_readback.py.)

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "modalcal/eigen.hpp"
#include "modalcal/vtu.hpp"
#include "modalcal/problem_file.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

namespace fs = std::filesystem;
using testing::LoadProblem;
using testing::WriteTempFile;

const char* kBar = R"(
mesh:
  element: hex8
  element_size: 0.5
  boxes: [{block: bar, min: [0, 0, 0], max: [2, 0.5, 0.5]}]
blocks:
  bar: {E: 1000, nu: 0.25, density: 2.0}
node_sets:
  root: {box: {min: [0, 0, 0], max: [0, 0.5, 0.5]}}
fixed:
  - {node_set: root, dofs: [x, y, z]}
parameters:
  E: {targets: [bar.E], initial: 1000, lower: 10, upper: 1e5, truth: 1200}
sensors:
  - {at: [2, 0.5, 0.5], directions: [y, z]}
measured:
  modes:
    - {frequency_hz: 1.5, shape: [0.25, -0.5]}
options:
  num_modes: 3
)";

std::string Read(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

int Count(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

struct Bar {
  Problem problem;
  std::unique_ptr<ParametricSystem> system;
  ModalResult modal;
  Vector p;
  explicit Bar(const std::string& path) : problem(LoadProblem(path)) {
    system = std::make_unique<ParametricSystem>(problem.model, problem.parameter_targets());
    p = problem.initial_values();
    SparseMatrix K, M;
    system->assemble(p, &K, &M);
    ModalOptions options;
    options.num_modes = 3;
    options.max_rigid_modes = 0;
    ModalSolver solver(system->pattern(), options);
    modal = solver.solve(K, M);
  }
};

TEST(Vtu, ModelGridHasEveryNodeEveryElementAndTheFields) {
  Bar bar(WriteTempFile("bar.yaml", kBar));
  ASSERT_EQ(bar.modal.status, EigenStatus::Successful);
  VtuFields fields;
  add_mode_fields(bar.modal, -1, &fields);
  const VtkGrid grid = model_grid(bar.problem, *bar.system, bar.p, fields);
  const Model& model = bar.problem.model;
  EXPECT_EQ(grid.points.cols(), model.num_nodes());
  ASSERT_EQ(static_cast<int>(grid.types.size()), model.num_elements());
  EXPECT_EQ(grid.types[0], VtkCellType::Hexahedron);
  // block_id, 7 properties; node_id and 3 modes.
  ASSERT_EQ(grid.cell_data.size(), 8u);
  EXPECT_EQ(grid.cell_data[1].name, "E");
  EXPECT_EQ(grid.cell_data[3].name, "K");
  EXPECT_CLOSE(grid.cell_data[3].values[0], 1000 / (3 * (1 - 2 * 0.25)), 1e-14);
  ASSERT_EQ(grid.point_data.size(), 4u);
  const double hz = frequency_hz(bar.modal.eigenvalues[1]);
  EXPECT_EQ(grid.point_data[2].name, shape_field_name("mode", 2, hz));
  // The last node's y displacement in mode 2, through the DOF map.
  const int corner = model.num_nodes() - 1;
  EXPECT_EQ(grid.point_data[2].values[3 * corner + 1],
            bar.system->dof_map().value(bar.modal.modes.col(1), corner, 1));

  const std::string document = vtu_document(grid);
  EXPECT_EQ(Count(document, "<DataArray"), 8 + 4 + 1 + 3 + 2);  // + points, cells, field frequencies + E
  EXPECT_NE(document.find("NumberOfCells=\"" + std::to_string(model.num_elements()) + "\""), std::string::npos);
  EXPECT_NE(document.find("Name=\"block_names\" NumberOfTuples=\"1\" format=\"ascii\">\n          98 97 114 0"),
            std::string::npos)
      << "block name 'bar' as character codes ending in 0";
}

TEST(Vtu, SensorGridCarriesMeasuredShapesPerDirection) {
  Bar bar(WriteTempFile("bar.yaml", kBar));
  const VtkGrid grid = sensor_grid(bar.problem);
  ASSERT_EQ(grid.points.cols(), 1);
  EXPECT_EQ(grid.types[0], VtkCellType::Vertex);
  ASSERT_EQ(grid.point_data.size(), 3u);
  EXPECT_EQ(grid.point_data[1].values, std::vector<double>{2});  // y and z sensed
  EXPECT_EQ(grid.point_data[2].name, "measured_1_1.50Hz");
  EXPECT_EQ(grid.point_data[2].values, (std::vector<double>{0, 0.25, -0.5}));
}

TEST(Vtu, BadFieldSizeIsRefusedBeforeAnyFileIsWritten) {
  Bar bar(WriteTempFile("bar.yaml", kBar));
  VtuFields fields;
  fields.element_data.push_back({"wrong", 1, {1.0, 2.0}});
  const fs::path dir = fs::path(WriteTempFile("marker", "")).parent_path() / "out";
  EXPECT_THROW(write_vtu_set(dir.string(), "x", bar.problem, *bar.system, bar.p, fields), std::invalid_argument);
  EXPECT_TRUE(fs::is_empty(dir));
}

TEST(Vtu, NeverOverwritesTheProblemFile) {
  // A problem file that happens to carry the name of an output: nothing may be written.
  const std::string path = WriteTempFile("x.vtu", kBar);
  Bar bar(path);
  const fs::path dir = fs::path(path).parent_path();
  EXPECT_THROW(write_vtu_set(dir.string(), "x", bar.problem, *bar.system, bar.p, {}), std::invalid_argument);
  EXPECT_EQ(Read(path), kBar);
  EXPECT_FALSE(fs::exists(dir / "x_sensors.vtu"));
  EXPECT_FALSE(fs::exists(dir / "x.pvd"));
}

TEST(Vtu, AFailedWriteLeavesWholeFilesOnlyAndNoTemporaries) {
  Bar bar(WriteTempFile("bar.yaml", kBar));
  const fs::path dir = fs::path(WriteTempFile("marker", "")).parent_path() / "out";
  fs::create_directories(dir / "x_sensors.vtu");  // a directory where the second file should go
  // A directory given as an output file is a bad output name (the CLI's exit 2).
  EXPECT_THROW(write_vtu_set(dir.string(), "x", bar.problem, *bar.system, bar.p, {}), std::invalid_argument);
  const std::string first = Read((dir / "x.vtu").string());
  EXPECT_EQ(first.substr(first.size() - 11), "</VTKFile>\n");
  for (const auto& entry : fs::directory_iterator(dir))
    EXPECT_NE(entry.path().filename().string()[0], '.') << "temporary file left: " << entry.path();
  EXPECT_FALSE(fs::exists(dir / "x.pvd"));
}

}  // namespace
}  // namespace modalcal
