// Atomic output: whole files only, never an input, and the permissions of an ordinary new file.

#include <filesystem>
#include <fstream>
#include <sstream>
#include <sys/stat.h>

#include "modalcal/output.hpp"
#include "test_util.hpp"

namespace modalcal {
namespace {

TEST(Output, WritesWholeFilesWithTheUmasksPermissions) {
  const std::string path = testing::WriteTempFile("out.json", "old");
  write_file_atomically(path, "{\"a\": 1}\n", {});
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), "{\"a\": 1}\n");
  const mode_t mask = ::umask(0);
  ::umask(mask);
  struct stat st {};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0666 & ~mask);  // not mkstemp's 0600
  for (const auto& entry : std::filesystem::directory_iterator(std::filesystem::path(path).parent_path()))
    EXPECT_EQ(entry.path().filename().string().rfind(".out.json.", 0), std::string::npos) << "temporary left behind";
}

TEST(Output, RefusesToOverwriteAnInput) {
  const std::string input = testing::WriteTempFile("problem.yaml", "name: x\n");
  EXPECT_THROW(write_file_atomically(input, "oops", {input}), std::invalid_argument);
  std::ifstream in(input);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str(), "name: x\n");
}

}  // namespace
}  // namespace modalcal
