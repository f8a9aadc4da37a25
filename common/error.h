// Errors and invariant checks shared by every dmmr library.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace dmmr {

// A user-facing error: bad input, a bad file, a bad option. Its message names
// the file (and field or line where known) and says what is wrong.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

// Builds "path: what" or "path:line: what" messages.
std::string fileError(const std::string& path, const std::string& what);
std::string fileError(const std::string& path, long line, const std::string& what);

[[noreturn]] void checkFailed(const char* expr, const char* file, int line, const std::string& msg);

}  // namespace dmmr

// CHECK guards internal invariants (programming errors), never user input.
#define DMMR_CHECK(cond)                                             \
  do {                                                               \
    if (!(cond)) ::dmmr::checkFailed(#cond, __FILE__, __LINE__, {}); \
  } while (0)
#define DMMR_CHECK_MSG(cond, msg)                                           \
  do {                                                                      \
    if (!(cond)) {                                                          \
      std::ostringstream dmmr_check_os_;                                    \
      dmmr_check_os_ << msg;                                                \
      ::dmmr::checkFailed(#cond, __FILE__, __LINE__, dmmr_check_os_.str()); \
    }                                                                       \
  } while (0)
