#include "stage_turns.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "error.h"

namespace dmmr {

StageTurns::StageTurns(const std::string& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
  if (fd_ < 0)
    throw Error(fileError(
        path, std::string("cannot open the stage-turns lock file: ") + std::strerror(errno)));
}

StageTurns::~StageTurns() {
  if (fd_ >= 0) ::close(fd_);  // releases a held lock too
}

void StageTurns::take() {
  if (held_) return;
  int rc;
  do rc = ::flock(fd_, LOCK_EX);
  while (rc != 0 && errno == EINTR);
  if (rc != 0)
    throw Error(
        fileError(path_, std::string("cannot lock the stage-turns file: ") + std::strerror(errno)));
  held_ = true;
}

void StageTurns::give() {
  if (!held_) return;
  ::flock(fd_, LOCK_UN);
  held_ = false;
}

}  // namespace dmmr
