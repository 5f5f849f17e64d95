// Problem files: load_problem() on the input as a problem YAML.
//
// The input is written as input.yaml into a folder that also holds, under their own names, every
// file of every problems/<name>/ folder of the repository (the first of a name wins: the bundled
// problems' synthetic.yaml differ), the universal files of tests/data/uff/, examples/data/ and
// the seed meshes and test data of fuzz/seeds/; beside that folder are copies of the problems/
// folders themselves. So the seeds (the bundled problems) keep their meaning (`extends:
// frame.yaml`, `extends: ../lfu/lfu.yaml`, `measured: {file: top-mass-data.yaml}`, `mesh: {file:
// bracket.msh}`, `test_data: {file: ...uff}`) and the fuzzer reaches the base files, data files,
// meshes and test data a problem names, which are fixed: a problem file and the files it names
// are fuzzed by their own targets (a data file is YAML of the problem loader's own, read by the
// same code as the problem file).
//
// Kept cheap so that a million executions fit in an hour: meshes whose modal solve would need
// more than 50 MB (about 1,600 nodes: the portal frame and the propped cantilever load whole,
// the LFU's 3,500 to 5,000 nodes are refused) are refused (LoadOptions::memory_bytes), synthetic
// measurements are checked but not computed (load_problem never solves the truth model), and sibling files
// over 64 kB (bracket.msh, the large universal files) are left out: loading reads, meshes and
// validates the problem, and never assembles or solves it. fuzz/seeds/problem/ has small problems
// that use a mesh file and test data, as the bundled ones that did are now refused early.
#include <filesystem>

#include "fuzz_input.hpp"
#include "modalcal/problem.hpp"
#include "modalcal/problem_file.hpp"

namespace fs = std::filesystem;

namespace {

void copy_files(const fs::path& from, const fs::path& to) {
  fs::create_directories(to);
  for (const fs::directory_entry& e : fs::directory_iterator(from))
    if (e.is_regular_file() && e.file_size() <= 64000 && !fs::exists(to / e.path().filename()))
      fs::copy_file(e.path(), to / e.path().filename());
}

const std::string& problem_dir() {
  static const std::string dir = [] {
    const fs::path source = MODALCAL_SOURCE_DIR;
    const fs::path root = fs::path(modalcal::fuzz::scratch_dir()) / "problems";
    const fs::path flat = root / "fuzz";
    for (const fs::directory_entry& e : fs::directory_iterator(source / "problems"))
      if (e.is_directory()) {
        copy_files(e.path(), root / e.path().filename());
        copy_files(e.path(), flat);
      }
    copy_files(source / "tests" / "data" / "uff", flat);
    copy_files(source / "examples" / "data", flat);
    for (const fs::directory_entry& e : fs::directory_iterator(source / "fuzz" / "seeds"))
      if (e.is_directory()) copy_files(e.path(), flat);
    return flat.string();
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return modalcal::fuzz::read_as_file(
      data, size, "input.yaml",
      [](const std::string& path) {
        modalcal::LoadOptions options;
        options.memory_bytes = 5e7;
        (void)modalcal::load_problem(path, options);
      },
      problem_dir());
}
