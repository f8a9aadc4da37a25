#include "atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>

#include "error.h"

namespace dmmr {

void writeFileAtomic(const std::string& path, std::string_view bytes) {
  std::string tmp = path + ".tmp." + std::to_string(::getpid());
  int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw Error(fileError(path, std::string("cannot create: ") + std::strerror(errno)));
  if (int e = writeAll(fd, bytes)) {
    ::close(fd);
    ::unlink(tmp.c_str());
    throw Error(fileError(path, std::string("write failed: ") + std::strerror(e)));
  }
  if (::close(fd) != 0 || std::rename(tmp.c_str(), path.c_str()) != 0) {
    int e = errno;
    ::unlink(tmp.c_str());
    throw Error(fileError(path, std::string("cannot finish writing: ") + std::strerror(e)));
  }
}

int writeAll(int fd, std::string_view bytes) {
  const char* p = bytes.data();
  size_t left = bytes.size();
  while (left > 0) {
    ssize_t n = ::write(fd, p, left);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return errno;
    p += n;
    left -= size_t(n);
  }
  return 0;
}

void writeFileAtomic(const std::string& path, const std::vector<uint8_t>& bytes) {
  writeFileAtomic(path,
                  std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

std::vector<uint8_t> readFileBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary | std::ios::ate);
  if (!f) throw Error(fileError(path, "cannot open"));
  std::streamoff size = f.tellg();
  if (size < 0) throw Error(fileError(path, "cannot read size"));
  std::vector<uint8_t> data(static_cast<size_t>(size));
  f.seekg(0);
  if (size > 0 && !f.read(reinterpret_cast<char*>(data.data()), size))
    throw Error(fileError(path, "read failed"));
  return data;
}

}  // namespace dmmr
