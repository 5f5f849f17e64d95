// Writes the Exodus II seeds of fuzz/seeds/exodus/ (small meshes in the netCDF layouts the
// Exodus library writes, with names, a node number map, node sets and side sets):
//   g++ -std=c++17 fuzz/seeds/make_exodus_seeds.cpp -lexoIIv2c -o /tmp/make_exodus_seeds
//   /tmp/make_exodus_seeds fuzz/seeds/exodus
#include <exodusII.h>

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace {

struct Block {
  const char* name;
  int64_t id;
  const char* type;
  int nodes_per_element;
  std::vector<int64_t> connectivity;
};

void put_names(int exo, ex_entity_type type, std::vector<const char*> names) {
  ex_put_names(exo, type, const_cast<char**>(names.data()));
}

bool write(const std::string& path, int mode, const std::vector<double>& x, const std::vector<double>& y,
           const std::vector<double>& z, const std::vector<Block>& blocks, bool sets) {
  int cpu = sizeof(double), io = sizeof(double);
  const int exo = ex_create(path.c_str(), EX_CLOBBER | mode, &cpu, &io);
  if (exo < 0) return false;
  ex_set_int64_status(exo, EX_ALL_INT64_API);
  int64_t elements = 0;
  for (const Block& b : blocks) elements += static_cast<int64_t>(b.connectivity.size()) / b.nodes_per_element;
  ex_put_init(exo, "modalcal fuzz seed", 3, static_cast<int64_t>(x.size()), elements,
              static_cast<int64_t>(blocks.size()), sets ? 1 : 0, sets ? 1 : 0);
  ex_put_coord(exo, x.data(), y.data(), z.data());
  std::vector<int64_t> map;
  for (size_t i = 0; i < x.size(); ++i) map.push_back(static_cast<int64_t>(101 + i));
  ex_put_id_map(exo, EX_NODE_MAP, map.data());
  std::vector<const char*> names;
  for (const Block& b : blocks) {
    const int64_t n = static_cast<int64_t>(b.connectivity.size()) / b.nodes_per_element;
    ex_put_block(exo, EX_ELEM_BLOCK, b.id, b.type, n, b.nodes_per_element, 0, 0, 0);
    ex_put_conn(exo, EX_ELEM_BLOCK, b.id, b.connectivity.data(), nullptr, nullptr);
    names.push_back(b.name);
  }
  put_names(exo, EX_ELEM_BLOCK, names);
  if (sets) {
    const std::vector<int64_t> nodes = {1, 2, 3};
    ex_put_set_param(exo, EX_NODE_SET, 7, 3, 0);
    ex_put_set(exo, EX_NODE_SET, 7, nodes.data(), nullptr);
    put_names(exo, EX_NODE_SET, {"base"});
    const std::vector<int64_t> elems = {1}, sides = {1};
    ex_put_set_param(exo, EX_SIDE_SET, 9, 1, 0);
    ex_put_set(exo, EX_SIDE_SET, 9, elems.data(), sides.data());
    put_names(exo, EX_SIDE_SET, {"front"});
  }
  return ex_close(exo) >= 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string dir = argc > 1 ? argv[1] : ".";
  // Two hex8 in a row: nodes 1-12.
  const std::vector<double> hx = {0, 1, 1, 0, 0, 1, 1, 0, 2, 2, 2, 2}, hy = {0, 0, 1, 1, 0, 0, 1, 1, 0, 1, 0, 1},
                            hz = {0, 0, 0, 0, 1, 1, 1, 1, 0, 0, 1, 1};
  const Block hexes{"part", 1, "HEX8", 8, {1, 2, 3, 4, 5, 6, 7, 8, 2, 9, 10, 3, 6, 11, 12, 7}};
  // One tet4 and one tet10.
  const std::vector<double> tx = {0, 1, 0, 0, 0.5, 0.5, 0, 0, 0.5, 0}, ty = {0, 0, 1, 0, 0, 0.5, 0.5, 0, 0, 0.5},
                            tz = {0, 0, 0, 1, 0, 0, 0, 0.5, 0.5, 0.5};
  const Block tet4{"corner", 3, "TETRA", 4, {1, 2, 3, 4}};
  const Block tet10{"curved", 4, "TETRA10", 10, {1, 2, 3, 4, 5, 6, 7, 8, 9, 10}};
  bool ok = write(dir + "/hex8.exo", 0, hx, hy, hz, {hexes}, true);
  ok &= write(dir + "/hex8_normal_model.e", EX_NORMAL_MODEL, hx, hy, hz, {hexes}, true);
  ok &= write(dir + "/tets.exo", 0, tx, ty, tz, {tet4, tet10}, true);
  ok &= write(dir + "/hex8_netcdf4.exo", EX_NETCDF4, hx, hy, hz, {hexes}, false);
  if (!ok) std::fprintf(stderr, "could not write every seed\n");
  return ok ? 0 : 1;
}
