#pragma once
// What libmodalcal exports. The library is built with -fvisibility=hidden: a symbol leaves the
// shared library only when its declaration in include/modalcal/ carries MODALCAL_EXPORT, so the
// private stages (src/), the template code they instantiate (Eigen, yaml-cpp, nlohmann, Ipopt) and
// the internal helpers stay inside. The tests, benchmarks and fuzz targets, which reach the
// private headers in src/, link the static library modalcal_internal instead.
//
//   class MODALCAL_EXPORT ModalSolver { ... };
//   MODALCAL_EXPORT Problem load_problem(const std::string& path, const LoadOptions& options = {});

#if defined(__GNUC__) || defined(__clang__)
#define MODALCAL_EXPORT __attribute__((visibility("default")))
#else
#define MODALCAL_EXPORT
#endif
