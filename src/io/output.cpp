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

namespace {

fs::path folder_of(const fs::path& target) { return target.has_parent_path() ? target.parent_path() : fs::path("."); }

/// What both the check and the write require: not an input, in a folder that exists, not a folder.
void check_target(const std::string& path, const std::vector<std::string>& inputs) {
  check_not_input(path, inputs);
  const fs::path dir = folder_of(path);
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw std::invalid_argument("cannot write '" + path + "': directory '" + dir.string() +
                                "' does not exist; create it first");
  if (fs::is_directory(path, ec))
    throw std::invalid_argument("cannot write '" + path + "': it is a directory; give a file name");
}

size_t longest_name(const fs::path& dir) {
  const long n = ::pathconf(dir.c_str(), _PC_NAME_MAX);
  return n > 0 ? static_cast<size_t>(n) : 255;
}

/// The temporary file beside the target: the target's name, hidden, with mkstemp's six
/// characters; a short one when that would pass the file system's limit on a name.
std::string temporary_template(const fs::path& target) {
  const fs::path dir = folder_of(target);
  const std::string name = "." + target.filename().string() + ".XXXXXX";
  return (dir / (name.size() <= longest_name(dir) ? name : std::string(".modalcal.XXXXXX"))).string();
}

bool is_special_file(const std::string& path) {
  std::error_code ec;
  const fs::file_status status = fs::symlink_status(path, ec);
  return fs::exists(status) && !fs::is_regular_file(status);
}

}  // namespace

// Creating (and removing) the temporary file the write will use tells, before any computation,
// what only the write would otherwise find: a folder that takes no new files (read-only, /proc).
void check_output_path(const std::string& path, const std::vector<std::string>& inputs) {
  check_target(path, inputs);
  const fs::path target(path);
  const size_t limit = longest_name(folder_of(target));
  if (target.filename().string().size() > limit)
    throw std::invalid_argument("cannot write '" + path + "': the file name is longer than the " +
                                std::to_string(limit) + " characters the file system allows");
  if (is_special_file(path)) return;  // written in place, as a redirection would
  std::string probe = temporary_template(target);
  const int fd = mkstemp(probe.data());
  if (fd < 0)
    throw std::invalid_argument("cannot write '" + path + "': no file can be created in '" +
                                folder_of(target).string() + "': " + std::strerror(errno));
  ::close(fd);
  std::remove(probe.c_str());
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
  check_target(path, inputs);
  if (is_special_file(path)) return write_in_place(path, content);
  std::string temp = temporary_template(path);
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
