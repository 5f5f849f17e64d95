// Replays inputs through a fuzz target without libFuzzer, in any build (the g++ test suite runs
// it as FuzzReplay.<target>): every regular file named on the command line, and every file under
// a named folder whose name ends in one of the --ext endings (all files of a folder given after
// --all). Folders named .git or starting with "build" are not entered.
//
//   fuzz_replay_uff --ext=.uff,.unv <repository> --all fuzz/regressions/uff
//
// An input fails if the target lets an exception out (anything but the ProblemError that bad
// input gets) or takes more than 10 s; a crash ends the program, naming the input first.
// Prints "N passed, N failed" and exits 1 if any failed or no input was found.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace fs = std::filesystem;

namespace {

std::vector<std::string> split_endings(const std::string& list) {
  std::vector<std::string> out;
  std::stringstream in(list);
  for (std::string e; std::getline(in, e, ',');)
    if (!e.empty()) out.push_back(e);
  return out;
}

bool ends_with_any(const std::string& name, const std::vector<std::string>& endings) {
  for (const std::string& e : endings)
    if (name.size() >= e.size() && name.compare(name.size() - e.size(), e.size(), e) == 0) return true;
  return false;
}

void collect(const fs::path& dir, const std::vector<std::string>* endings, std::vector<fs::path>* files) {
  for (auto it = fs::recursive_directory_iterator(dir); it != fs::recursive_directory_iterator(); ++it) {
    const std::string name = it->path().filename().string();
    if (it->is_directory() && (name == ".git" || name.rfind("build", 0) == 0)) {
      it.disable_recursion_pending();
      continue;
    }
    if (it->is_regular_file() && (!endings || ends_with_any(name, *endings))) files->push_back(it->path());
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> endings;
  std::vector<fs::path> files;
  bool all = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg.rfind("--ext=", 0) == 0) {
      endings = split_endings(arg.substr(6));
    } else if (arg == "--all") {
      all = true;
    } else if (fs::is_directory(arg)) {
      collect(arg, all ? nullptr : &endings, &files);
    } else if (fs::is_regular_file(arg)) {
      files.push_back(arg);
    } else {
      std::cerr << "no such file or folder: " << arg << "\n";
      return 2;
    }
  }
  std::sort(files.begin(), files.end());
  int passed = 0, failed = 0;
  double slowest = 0;
  std::string slowest_file;
  for (const fs::path& file : files) {
    std::ifstream in(file, std::ios::binary);
    const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    std::cerr << "input " << file.string() << "\n";  // before a crash can end the program
    const auto start = std::chrono::steady_clock::now();
    try {
      LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
    } catch (const std::exception& e) {
      std::cout << "FAILED " << file.string() << ": unexpected exception: " << e.what() << "\n";
      ++failed;
      continue;
    } catch (...) {
      std::cout << "FAILED " << file.string() << ": unexpected exception of an unknown type\n";
      ++failed;
      continue;
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (seconds > slowest) slowest = seconds, slowest_file = file.string();
    if (seconds > 10) {
      std::cout << "FAILED " << file.string() << ": took " << seconds << " s\n";
      ++failed;
      continue;
    }
    ++passed;
  }
  if (!slowest_file.empty()) std::cout << "slowest input: " << slowest_file << " (" << slowest << " s)\n";
  std::cout << passed << " passed, " << failed << " failed\n";
  return failed > 0 || files.empty() ? 1 : 0;
}
