#include <fruit_shape_completion/atomic_file.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>

namespace fruit_shape_completion {

bool writeFileAtomically(const std::string& path, const std::string& bytes, std::string* error) {
  auto fail = [&](const std::string& what, const std::string& tmp) {
    const int err = errno;
    if (error) *error = path + ": " + what + " (" + std::strerror(err) + ")";
    if (!tmp.empty()) ::unlink(tmp.c_str());
    return false;
  };
  std::string tmp = path + ".tmpXXXXXX";
  const int fd = ::mkstemp(&tmp[0]);
  if (fd < 0) return fail("cannot create a temporary file beside it", "");
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      ::close(fd);
      return fail("write error", tmp);
    }
    done += static_cast<std::size_t>(n);
  }
  // mkstemp makes the file 0600; a saved map is an ordinary file for its user's tools.
  ::fchmod(fd, 0644);
  if (::fsync(fd) != 0) {
    ::close(fd);
    return fail("cannot flush to the disk", tmp);
  }
  if (::close(fd) != 0) return fail("cannot close", tmp);
  if (::rename(tmp.c_str(), path.c_str()) != 0) return fail("cannot replace", tmp);
  return true;
}

std::vector<std::string> removeStaleTemporaries(const std::string& path, double min_age) {
  namespace fs = std::filesystem;
  std::vector<std::string> removed;
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  const std::string prefix = target.filename().string() + ".tmp";
  std::error_code ec;
  fs::directory_iterator it(dir, ec), end;
  if (ec) return removed;
  const auto now = fs::file_time_type::clock::now();
  for (; it != end; it.increment(ec)) {
    if (ec) break;
    const std::string name = it->path().filename().string();
    if (name.size() != prefix.size() + 6 || name.compare(0, prefix.size(), prefix) != 0) continue;
    if (!it->is_regular_file(ec)) continue;
    const auto modified = fs::last_write_time(it->path(), ec);
    if (ec || std::chrono::duration<double>(now - modified).count() < min_age) continue;
    if (fs::remove(it->path(), ec)) removed.push_back(it->path().string());
  }
  return removed;
}

}  // namespace fruit_shape_completion
