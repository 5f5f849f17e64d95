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

// A name of 250 characters is legal; the hidden temporary beside it ('.' + name + ".XXXXXX") would
// not be, so the write takes a shorter temporary and leaves none behind.
TEST(Output, ANameNearTheFileSystemsLimitIsWritten) {
  const std::filesystem::path dir = std::filesystem::path(testing::WriteTempFile("keep", "")).parent_path();
  const std::string path = (dir / (std::string(245, 'n') + ".json")).string();
  EXPECT_NO_THROW(check_output_path(path, {}));
  write_file_atomically(path, "{}\n", {});
  EXPECT_EQ(testing::ReadFile(path), "{}\n");
  for (const auto& entry : std::filesystem::directory_iterator(dir))
    EXPECT_NE(entry.path().filename().string()[0], '.') << "temporary left behind: " << entry.path();
}

// What only the write would find, found before a command computes anything (exit 2 from the CLI).
TEST(Output, AnOutputThatCannotBeCreatedIsRefusedUpFront) {
  const std::string folder = std::filesystem::path(testing::WriteTempFile("keep", "")).parent_path().string();
  try {
    check_output_path(folder + "/" + std::string(300, 'n') + ".json", {});
    ADD_FAILURE() << "a 305-character name was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("characters the file system allows"), std::string::npos) << e.what();
  }
  try {
    check_output_path("/proc/modalcal-output-check.json", {});
    ADD_FAILURE() << "a file under /proc was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("no file can be created in '/proc'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(check_output_path(folder, {}), std::invalid_argument);  // a directory
  EXPECT_NO_THROW(check_output_path("/dev/null", {}));                // written through, not created
}

TEST(Output, TheCliRefusesAnUncreatableOutputBeforeTheRun) {
  const std::string problem = testing::WriteTempFile("bar.yaml", testing::CantileverBar() + "options: {num_modes: 2}\n");
  const testing::CliRun run = testing::RunCli("modes " + problem + " --json /proc/modalcal-output-check.json");
  EXPECT_EQ(run.exit_code, 2) << run.output;
  EXPECT_NE(run.output.find("no file can be created in '/proc'"), std::string::npos) << run.output;
  EXPECT_EQ(run.output.find("DOFs"), std::string::npos) << "the model was solved first:\n" << run.output;
}

}  // namespace
}  // namespace modalcal
