#include "modalcal/output.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <sys/stat.h>
#include <unistd.h>

namespace modalcal {

namespace fs = std::filesystem;

void check_not_input(const std::string& path, const std::vector<std::string>& inputs) {
  std::error_code ec;
  for (const std::string& input : inputs)
    if (fs::exists(path, ec) && fs::equivalent(path, input, ec))
      throw std::invalid_argument("refusing to write '" + path + "': it is an input (" + input +
                                  "); choose another output name");
}

void check_output_path(const std::string& path, const std::vector<std::string>& inputs) {
  check_not_input(path, inputs);
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw std::invalid_argument("cannot write '" + path + "': directory '" + dir.string() +
                                "' does not exist; create it first");
}

namespace {

/// Writes through an existing target that is not a regular file of its own (/dev/stdout, /dev/null,
/// a FIFO, a symbolic link), as a shell redirection would: renaming a temporary file onto it
/// would replace the device or the link with a regular file.
void write_in_place(const std::string& path, const std::string& content) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (out) out.write(content.data(), static_cast<std::streamsize>(content.size()));
  out.flush();
  if (!out) throw std::runtime_error("cannot write '" + path + "': " + std::strerror(errno));
}

}  // namespace

void write_file_atomically(const std::string& path, const std::string& content,
                           const std::vector<std::string>& inputs) {
  check_output_path(path, inputs);
  std::error_code ec;
  if (fs::is_directory(path, ec))
    throw std::invalid_argument("cannot write '" + path + "': it is a directory; give a file name");
  const fs::file_status status = fs::symlink_status(path, ec);
  if (fs::exists(status) && !fs::is_regular_file(status)) return write_in_place(path, content);
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::string temp = (dir / ("." + target.filename().string() + ".XXXXXX")).string();
  const int fd = mkstemp(temp.data());
  if (fd < 0)
    throw std::runtime_error("cannot write '" + path + "': " + std::strerror(errno));
  // mkstemp creates the file 0600; an output should get the permissions of any new file
  // (0666 less the umask), as if written directly.
  const mode_t mask = ::umask(0);
  ::umask(mask);
  const bool written = ::fchmod(fd, 0666 & ~mask) == 0 && ::write(fd, content.data(), content.size()) == static_cast<ssize_t>(content.size()) &&
                       ::fsync(fd) == 0;
  ::close(fd);
  if (!written || std::rename(temp.c_str(), path.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    std::remove(temp.c_str());
    throw std::runtime_error("cannot write '" + path + "': " + reason);
  }
}

}  // namespace modalcal
